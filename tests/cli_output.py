"""What a command printed, as the CLI tests read it."""

from __future__ import annotations


def one_line(capsys) -> str:
    """The error the command printed: exactly one line on stderr, no traceback."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("pronet: "), err
    return lines[0]
