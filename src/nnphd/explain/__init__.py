"""Explain a learned non-conservative force f_n by fitting candidate formulas to it (paper §III.A.3, Table II)."""
