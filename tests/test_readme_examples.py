"""The README's command-line examples write into the scratch folder ``out/``, never over a
tracked file (such as the pictures in ``docs/images``)."""

from __future__ import annotations

import itertools
import re
import shlex
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
#: Options whose value is a file the command writes.
OUTPUTS = {"-o", "--output", "--screenshot"}


def _commands(text: str) -> list[list[str]]:
    """Every ``meshrec ...`` command of the README, from code blocks and inline code."""
    spans = re.findall(r"^```[a-z]*\n(.*?)^```$", text, flags=re.S | re.M)
    rest = re.sub(r"^```[a-z]*\n.*?^```$", "", text, flags=re.S | re.M)
    spans += re.findall(r"`([^`]+)`", rest)
    commands = []
    for span in spans:
        for line in span.replace("\\\n", " ").splitlines():
            line = " ".join(line.split())
            if line.startswith("meshrec ") and "..." not in line and "[" not in line:
                commands.append(shlex.split(line))
    return commands


def _written(args: list[str]) -> list[str]:
    out = [b for a, b in itertools.pairwise(args) if a in OUTPUTS]
    if args[1] == "simulate":  # simulate writes its truth file too
        out += [b for a, b in itertools.pairwise(args) if a == "--truth"]
    return out


def test_examples_write_only_into_the_scratch_folder():
    commands = _commands(README.read_text(encoding="utf-8"))
    written = [(" ".join(c), w) for c in commands for w in _written(c)]
    assert len(written) >= 8  # the simulate, show and plot examples were found
    bad = [(c, w) for c, w in written if not w.startswith("out/")]
    assert bad == []
