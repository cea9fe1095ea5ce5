"""The end of a benchmark script: print its Markdown report and write it where asked."""

from __future__ import annotations

from pathlib import Path


def finish(lines: list[str], out: Path | None) -> int:
    """Print the report's ``lines`` and write them to ``out`` (when given); return 0.

    Parameters
    ----------
    lines : list of str
        The report, one Markdown line each.
    out : Path, optional
        Where to write it as well.

    Returns
    -------
    int
        The script's exit status, 0.
    """
    text = "\n".join(lines) + "\n"
    print(text)
    if out:
        out.write_text(text)
    return 0
