"""Many recordings at once (``nnphd detect a.csv b.csv …`` or a folder): one report per file, one summary table.

Each file is one unit of :func:`nnphd.parallel.run_units` (local Dask workers, an existing cluster, or here in this
process).  Its report goes to ``out/<name>/`` (report.json, report.html, figures; ``<name>`` is the file's stem, made
unique); ``out/summary.csv``, ``summary.html`` and ``summary.json`` list every file's verdict, confidence, effect
size and law — or the one-line error of a file that could not be used (a bad file does not stop the others).

Resume: a finished file leaves ``out/<name>/batch.json`` with the file's SHA-256 and the settings; a rerun with the
same settings skips every file whose content has not changed and runs the rest.

What is read (:func:`scan_paths`): of a folder, only the regular ``.csv``/``.npz`` files directly in it — a symbolic
link is not followed (it could point anywhere, e.g. at a private key whose lines an error message would quote into a
summary the user shares), nor anything else that is not a regular file; each is listed as skipped.  A file named on
the command line is taken the same way (``data/*.csv`` may expand to a link or a FIFO).  Files inside
``out`` are nnphd's own output (summary.csv …) and never inputs: they are skipped too, and an ``out`` that is an
input folder is refused (a subfolder of it is fine: folders are not searched recursively).  Text cells of summary.csv that a spreadsheet would run as a formula get a
leading ``'`` (:func:`nnphd.io.escape.csv_cell`).
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import stat
import sys
import time
from collections.abc import Sequence
from enum import StrEnum
from pathlib import Path

from nnphd.explain.law import TableStatus
from nnphd.io.cache import Cache, open_regular, warn_ignored
from nnphd.io.errors import DataError
from nnphd.io.escape import csv_cell
from nnphd.io.html import escape, page, table
from nnphd.io.progress import Progress
from nnphd.io.results import atomic_write_bytes, ensure_writable_dir, write_json
from nnphd.parallel import Unit, n_workers, run_units
from nnphd.user.result import Status

__all__ = ["SUFFIXES", "expand_paths", "scan_paths", "detect_batch", "detect_one"]

SUFFIXES = (".csv", ".npz")
VERDICTS = tuple(Status)  # the verdicts a cached report may hold


class FileStatus(StrEnum):
    """The status of a file of the batch that holds no verdict (a row's ``status`` is otherwise the report's
    :class:`~nnphd.user.result.Status`). A str, written as the plain word.

    - ``ERROR``: the file was read but its detection failed (the message in ``error``);
    - ``SKIPPED``: an entry that was not read (summary.csv only; the reason in ``error``)."""

    ERROR = "error"
    SKIPPED = "skipped"


MARKER = "batch.json"
COLUMNS = (
    "name",
    "file",
    "status",
    "confidence",
    "effect",
    "law",
    "params",
    "wall_time_s",
    "training_s",
    "law_table_s",
    "compile_s",
    "cached",
    "error",
)


def expand_paths(paths: Sequence[str | Path], out: str | Path | None = None) -> list[Path]:
    """The files :func:`scan_paths` reads (without the list of skipped ones)."""
    return scan_paths(paths, out)[0]


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def scan_paths(paths: Sequence[str | Path], out: str | Path | None = None) -> tuple[list[Path], list[dict[str, str]]]:
    """(files, skipped): files as given, folders as the regular ``*.csv`` / ``*.npz`` files directly in them (sorted;
    not recursive; symbolic links and other non-regular entries are skipped, not followed); files inside the output
    folder ``out`` are skipped.  ``skipped``: ``{"file", "reason"}`` per entry left out.  An error names a path that
    does not exist, a folder with no file to read, an ``out`` that is an input folder, no file left, and a file given
    twice."""
    out_r = Path(out).resolve() if out is not None else None
    files: list[Path] = []
    skipped: list[dict[str, str]] = []
    for p in map(Path, paths):
        if p.is_dir():  # a folder named on the command line is read even through a link; its entries are not
            files.extend(_scan_folder(p, out_r, skipped))
        elif os.path.lexists(p):
            _add_named_file(p, files, skipped)
        else:
            raise ValueError(f"{p}: no such file or folder")
    if not files:
        why = f": {skipped[-1]['file']} is {skipped[-1]['reason']}" if skipped else ""
        raise ValueError(f"no .csv or .npz file to read{why}")
    if out_r is not None:
        inside = [f for f in files if _inside(f.resolve(), out_r)]
        for f in inside:
            _skip(skipped, f, "inside the --out folder (nnphd's own output), not read")
        files = [f for f in files if f not in inside]
        if not files:
            raise ValueError(f"every file given is inside the --out folder {out}; choose an --out outside the data")
    seen = set()
    for p in files:
        r = p.resolve()
        if r in seen:
            raise ValueError(f"{p}: the file is given twice")
        seen.add(r)
    return files, skipped


def _add_named_file(p: Path, files: list[Path], skipped: list[dict[str, str]]) -> None:
    """A file named on the command line, taken as a folder's entry would be: a symbolic link is not followed and a
    FIFO, device or socket is not opened (both skipped, with the reason), whatever its suffix."""
    st = os.lstat(p)
    if stat.S_ISLNK(st.st_mode):
        _skip(skipped, p, "symbolic link, not followed")
    elif not stat.S_ISREG(st.st_mode):
        _skip(skipped, p, "not a regular file")
    else:
        files.append(p)


def _skip(skipped: list[dict[str, str]], p: Path, why: str) -> None:
    """Record an entry left out, with the reason."""
    skipped.append({"file": str(p), "reason": why})


def _scan_folder(p: Path, out_r: Path | None, skipped: list[dict[str, str]]) -> list[Path]:
    """The regular ``*.csv`` / ``*.npz`` files directly in folder ``p``, sorted by name; the other entries with such a
    suffix go to ``skipped``.  Refuses the output folder ``out_r`` (resolved) and a folder with no file to read."""
    if out_r is not None and p.resolve() == out_r:
        raise ValueError(
            f"{p}: the input folder is the --out folder; nnphd would read its own output (summary.csv) as "
            f"data on the next run: choose another --out, e.g. {p / 'nnphd'}"
        )
    found, n_skip = [], len(skipped)
    with os.scandir(p) as it:
        entries = sorted(it, key=lambda e: e.name)
    for e in entries:
        f = Path(p, e.name)
        if f.suffix.lower() not in SUFFIXES:
            continue
        if e.is_symlink():
            _skip(skipped, f, "symbolic link, not followed")
        elif e.is_dir(follow_symlinks=False):
            _skip(skipped, f, "a folder, not read (folders are not searched recursively)")
        elif not e.is_file(follow_symlinks=False):
            _skip(skipped, f, "not a regular file")
        else:
            found.append(f)
    if not found:
        why = f" ({len(skipped) - n_skip} skipped: {skipped[-1]['reason']})" if len(skipped) > n_skip else ""
        raise ValueError(f"{p}: the folder holds no .csv or .npz file{why}")
    return found


def unique_names(paths: Sequence[Path]) -> list[str]:
    """A unique folder name per file: its stem (characters other than letters, digits and ``-_.+`` as ``_``; a leading
    ``.`` as ``_``, so ``..csv`` and ``...csv`` stay inside ``out``), with ``-2``, ``-3`` … where stems repeat."""
    names, used = [], set()
    for p in paths:
        base = "".join(c if c.isalnum() or c in "-_.+" else "_" for c in p.stem) or "file"
        base = "_" + base[1:] if base.startswith(".") else base
        name, k = base, 1
        while name.lower() in used or name.lower() in ("summary",):
            k += 1
            name = f"{base}-{k}"
        used.add(name.lower())
        names.append(name)
    return names


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a data file, streamed, opened as a regular file only: a FIFO or device swapped in after the
    scan is refused, never read or waited on."""
    h = hashlib.sha256()
    try:
        f = open_regular(path, sys.maxsize)
    except ValueError as e:
        raise DataError(f"{path}: {e}; expected a .csv or .npz file") from None
    with f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _cached_report(rep) -> dict:
    """A cached report.json as the summary reads it, checked (ValueError saying what is not as this version writes
    it): a verdict, a confidence in [0, 1] (or NaN), the law table, effect and timings of the right types."""
    if not isinstance(rep, dict) or rep.get("status") not in VERDICTS:
        raise ValueError("no verdict")
    conf = rep.get("confidence")
    if isinstance(conf, bool) or not isinstance(conf, (int, float)) or not (0 <= conf <= 1 or conf != conf):
        raise ValueError(f"confidence {conf!r:.40}")
    law = rep.get("law") or {}
    if not isinstance(law, dict) or not isinstance(law.get("law") or {}, dict):
        raise ValueError("the law table is not an object")
    for key, kind in (("effect", str), ("timings", dict), ("wall_time_s", (int, float))):
        if rep.get(key) is not None and not isinstance(rep[key], kind):
            raise ValueError(f"{key} of the wrong type")
    return rep


def _tie_prefix(law: dict) -> str:
    """ "tie (a or b): " when the record cannot tell the families apart (the formula shown is the first's)."""
    if law.get("status") != TableStatus.TIE:
        return ""
    return "tie (" + " or ".join(r.get("law", "?") for r in [law.get("law") or {}, *law.get("ties", [])]) + "): "


def summary_row(name: str, path: str, rep: dict, cached: bool) -> dict:
    law = (rep.get("law") or {}).get("law") or {}
    formula = law.get("formula") or {}  # a blind hint is never a law
    return {
        "name": name,
        "file": path,
        "status": rep["status"],
        "confidence": rep["confidence"],
        "effect": rep.get("effect"),
        "law": _tie_prefix(rep.get("law") or {}) + "; ".join(f"{k} = {v}" for k, v in formula.items()),
        "params": {k: [v, law.get("stderr", {}).get(k)] for k, v in (law.get("params") or {}).items()},
        "wall_time_s": rep.get("wall_time_s"),
        **_stage_seconds(rep.get("timings")),
        "cached": cached,
        "error": None,
    }


def _stage_seconds(tm: dict | None) -> dict:
    """Where a file's time went, for the summary: training with the trust checks, the law table, JAX compilation
    (of the whole run; None for a report without timings)."""
    if not tm:
        return {"training_s": None, "law_table_s": None, "compile_s": None}
    by = {s["stage"]: s["s"] for s in tm["stages"]}
    return {
        "training_s": by.get("training and trust checks"),
        "law_table_s": sum(v for k, v in by.items() if k.startswith("law table")),
        "compile_s": tm["compile_s"],
    }


def detect_one(path: str, out: str, name: str, angles: tuple = (), max_rows: int | None = None, **settings) -> dict:
    """One file of a batch (a module-level function, so a Dask worker can run it): its report in ``out`` (or the
    cached one when ``out/batch.json`` records the same file content and settings); returns its summary row."""
    from nnphd.user.detect import detect_file

    key = {"file_sha256": file_sha256(path), "angles": list(angles), "max_rows": max_rows, **settings}
    cache = Cache(out, key)
    sealed = cache.load_sealed(MARKER, "report.json")
    if sealed is not None:
        try:
            return summary_row(name, path, _cached_report(sealed[1]), True)
        except (ValueError, KeyError, TypeError) as e:  # a report of another version: run the file again
            warn_ignored(Path(out) / "report.json", f"not a report this version can summarise: {e}")
    rep = detect_file(path, out, angles=angles, max_rows=max_rows, **settings)
    cache.seal({"settings": key, "finished": time.time()}, MARKER, ("report.json",))
    return summary_row(name, path, rep, False)


def detect_batch(
    paths: Sequence[str | Path],
    out: str | Path,
    angles: Sequence[str] = (),
    max_rows: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress | None = None,
    **settings,
) -> dict:
    """Run :func:`nnphd.user.detect.detect_file` on every file (folders expanded by :func:`scan_paths`), each into
    ``out/<name>/``, as units on ``workers`` local processes (None: one per core; 1: here) or a Dask ``scheduler``;
    write ``summary.csv``, ``summary.html`` and ``summary.json`` to ``out`` and return the summary (``rows`` in the
    files' order, ``failed``: how many files gave an error; ``skipped``: the entries not read, with the reason)."""
    t0 = time.perf_counter()
    files, skipped = scan_paths(paths, out)
    outdir = ensure_writable_dir(out)
    names = unique_names(files)
    units = [
        Unit(
            n,
            detect_one,
            dict(path=str(p), out=str(outdir / n), name=n, angles=tuple(angles), max_rows=max_rows, **settings),
            cost=p.stat().st_size,  # the biggest files start first on the workers
        )  # fmt: skip
        for n, p in zip(names, files)
    ]
    outs = run_units(units, workers, scheduler, progress=progress)
    rows = []
    for u in units:
        o = outs[u.key]
        if o.ok:
            rows.append({**o.value, "where": o.where, "compile_time_s": o.compile_time_s})
        else:
            rows.append({c: None for c in COLUMNS} | {"name": u.key, "file": u.kwargs["path"], "status": FileStatus.ERROR, "error": o.error, "cached": False, "where": o.where})  # fmt: skip
    summary = {
        "rows": rows,
        "n_files": len(rows),
        "failed": sum(r["status"] == FileStatus.ERROR for r in rows),
        "counts": {s: sum(r["status"] == s for r in rows) for s in (*Status, FileStatus.ERROR)},
        "skipped": skipped,
        "workers": scheduler or n_workers(workers, None, len(units)),
        "settings": {"angles": list(angles), "max_rows": max_rows, **settings},
        "wall_time_s": time.perf_counter() - t0,
        "compute_time_s": sum(outs[u.key].wall_time_s for u in units),
        "compile_time_s": sum(outs[u.key].compile_time_s for u in units),
    }
    _write_summary(outdir, summary)
    return summary


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return "; ".join(f"{k} = {_cell(x[0])} ± {_cell(x[1])}" if isinstance(x, list) else f"{k} = {x}" for k, x in v.items())  # fmt: skip
    return str(v)


def _csv(v):
    """A summary.csv cell: numbers as :func:`_cell` writes them, text guarded against formula injection."""
    return _cell(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else csv_cell(_cell(v))


def _write_summary(outdir: Path, summary: dict) -> None:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(COLUMNS)
    for r in summary["rows"]:
        w.writerow([_csv(r.get(c)) for c in COLUMNS])
    for k in summary.get("skipped", []):  # the entries not read: status "skipped", the reason in "error"
        w.writerow([_csv(k["file"] if c == "file" else k["reason"] if c == "error" else FileStatus.SKIPPED if c == "status" else None) for c in COLUMNS])  # fmt: skip
    atomic_write_bytes(outdir / "summary.csv", buf.getvalue().encode())
    write_json(outdir / "summary.json", summary)
    rows = []
    for r in summary["rows"]:
        link = f'<a href="{escape(r["name"])}/report.html">{escape(r["name"])}</a>' if r["status"] != FileStatus.ERROR else escape(r["name"])  # fmt: skip
        st = escape(r["status"])
        rows.append(
            [
                link,
                escape(r["file"]),
                f'<span class="st-{st}">{st}</span>',
                escape(_cell(r["confidence"])),
                escape(_cell(r["effect"])),
                f"<code>{escape(r['law'])}</code>" if r.get("law") else "",
                escape(_cell(r["params"])),
                escape(_cell(r["wall_time_s"])),
                escape(_cell(r.get("training_s"))),
                escape(_cell(r.get("law_table_s"))),
                escape(_cell(r.get("compile_s"))),
                "yes" if r["cached"] else "",
                escape(r["error"] or ""),
            ]
        )
    c = summary["counts"]
    body = (
        "<h1>nnphd detect — batch summary</h1>"
        f"<p>{summary['n_files']} files: {c[Status.DETECTED]} detected, {c[Status.NONE]} none, "
        f"{c[Status.INCONCLUSIVE]} inconclusive, {c[FileStatus.ERROR]} errors; workers: {escape(summary['workers'])}; "
        "wall time "
        f"{summary['wall_time_s']:.0f} s (compute time of the files {summary['compute_time_s']:.0f} s, of which "
        f"{summary['compile_time_s']:.0f} s JAX compilation).</p>"
        + "".join(
            f"<p class='warn'>skipped {escape(k['file'])}: {escape(k['reason'])}</p>"
            for k in summary.get("skipped", [])
        )
        + table(
            [
                "report",
                "file",
                "verdict",
                "confidence",
                "effect",
                "law",
                "parameters ± stderr",
                "time (s)",
                "training (s)",
                "law table (s)",
                "compiling (s)",
                "cached",
                "error",
            ],  # fmt: skip
            rows,
            left=3,
        )
    )
    atomic_write_bytes(outdir / "summary.html", page("nnphd detect — batch summary", body).encode())
