"""nnphd.io.html: the shared pieces of the HTML reports, checked string for string."""

import base64

from nnphd.io.html import CSS, bullets, details, escape, figure, figure_file, figures, page, section, table


def test_escape():
    assert escape("<b>a & 'b'</b> \"c\"") == "&lt;b&gt;a &amp; &#x27;b&#x27;&lt;/b&gt; &quot;c&quot;"
    assert escape(1.5) == "1.5" and escape(None) == "None"


def test_table_escapes_the_header_not_the_cells():
    out = table(["x<1", "y & z"], [["<b>a</b>", 2], ["c", 3.5]], left=1, row_classes=["best"])
    assert out == (
        '<table><tr><th class="l">x&lt;1</th><th>y &amp; z</th></tr>'
        '<tr class="best"><td class="l"><b>a</b></td><td>2</td></tr>'
        '<tr><td class="l">c</td><td>3.5</td></tr></table>'
    )
    assert table(["a"], [], left=0) == "<table><tr><th>a</th></tr></table>"


def test_page_section_details_bullets():
    doc = page("a < b", "<p>x</p>")
    assert doc == (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>a &lt; b</title><style>{CSS}</style>"
        "</head><body><p>x</p></body></html>"
    )
    assert section("T & U", "<p>b</p>", "t-1") == '<section id="t-1"><h2>T &amp; U</h2><p>b</p></section>'
    assert section("T", "") == "<section><h2>T</h2></section>"
    assert details("s<", "a<b") == "<details><summary>s&lt;</summary><pre>a&lt;b</pre></details>"
    assert bullets(["<i>a</i>", "b"]) == "<ul><li><i>a</i></li><li>b</li></ul>"


def test_figures_embed_and_link(tmp_path):
    png = b"\x89PNG\r\n\x1a\nabc"
    data = base64.b64encode(png).decode()
    one = figure(png, "a&b.png")
    assert one == (
        f'<figure><img src="data:image/png;base64,{data}" alt="a&amp;b.png">'
        '<figcaption><a href="a&amp;b.png">a&amp;b.png</a></figcaption></figure>'
    )
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "f.png").write_bytes(png)
    assert figure_file(tmp_path, "sub/f.png") == figure(png, "sub/f.png")
    assert figure_file(tmp_path, "missing.png") == '<p class="miss">figure not produced: missing.png</p>'
    assert figures([one, "<p>x</p>"]) == f'<div class="fig">{one}<p>x</p></div>'
