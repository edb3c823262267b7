"""What the command line printed, checked against its contract for bad input."""

from __future__ import annotations


def one_error_line(capsys) -> str:
    """The captured stderr, which must be exactly one ``voxfield: error: …`` line."""
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("voxfield: error: "), err
    return err[0]
