"""Time of the whole ``meshrec next-touch`` command against the four bundled ``objects``.

For each bundled object, one seeded simulated touch (``meshrec.simulate_touch``) is
written to a file, and ``meshrec next-touch FILE --models objects --seed S --json`` is run
``--runs`` times as a new process (warm index cache: the first run of each is not timed).
Reported per object: the median CPU time of the process (user + system, from
``resource.getrusage(RUSAGE_CHILDREN)``: the machine is shared) and its median wall time,
and the same for the interpreter starting and importing what the command imports (the
package's import: the floor of any command).

Bytecode: an installed package is imported from its compiled bytecode (``pip install``
writes it; Python writes it on first import). This sandbox sets
``PYTHONDONTWRITEBYTECODE=1`` and installs meshrec editable, so by default every command
here would compile meshrec's sources again (measured: about 0.3 s of each command).
``--bytecode warm`` (the default) lets the children write bytecode to a temporary
``PYTHONPYCACHEPREFIX``, written by the untimed first run, as on a user's machine;
``--bytecode none`` keeps the environment as it is (no bytecode for meshrec).

    .venv/bin/python tools/next_touch_time.py --runs 3 --out reports/next_touch_time.md

Uses only meshrec's public API (and its command line).
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import meshrec

_IMPORT = "import meshrec; meshrec.recognize, meshrec.next_touch, meshrec.ModelLibrary"
_CLI = "import sys; from meshrec.app.cli import main; sys.exit(main())"


def _timed(cmd: list[str], env: dict) -> tuple[float, float, int]:
    """(CPU seconds, wall seconds, exit status) of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, done.returncode


def run(runs: int, seed: int, log, bytecode: str = "warm") -> list[dict]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(Path(meshrec.__file__).resolve().parents[1])
    library = meshrec.ModelLibrary.from_folder(meshrec.bundled_models_dir("objects"))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        if bytecode == "warm":
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
        _timed([sys.executable, "-c", _IMPORT], env)  # writes the bytecode (warm)
        floor = [_timed([sys.executable, "-c", _IMPORT], env) for _ in range(runs)]
        rows.append(
            {
                "what": "start-up and imports alone",
                "cpu": statistics.median(c for c, _, _ in floor),
                "wall": statistics.median(w for _, w, _ in floor),
                "verdict": "-",
            }
        )
        for name in library.names:
            path = Path(tmp) / f"{name}.csv"
            meshrec.simulate_touch(library[name], rng=seed).touch.to_file(path)
            cmd = [sys.executable, "-c", _CLI, "next-touch", str(path), "--models", "objects"]
            cmd += ["--seed", str(seed), "--json"]
            _timed(cmd, env)  # warms the index cache
            times = [_timed(cmd, env) for _ in range(runs)]
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
            verdict = out.stdout.split('"verdict": "')[-1].split('"')[0] if out.stdout else "?"
            rows.append(
                {
                    "what": f"next-touch, a touch on {name}",
                    "cpu": statistics.median(c for c, _, _ in times),
                    "wall": statistics.median(w for _, w, _ in times),
                    "verdict": verdict,
                }
            )
            log(f"{name}: cpu {rows[-1]['cpu']:.2f} s wall {rows[-1]['wall']:.2f} s {verdict}")
    return rows


def report(rows, args, seconds) -> str:
    lines = [
        "# `meshrec next-touch`: time of the whole command",
        "",
        f"Command: `python tools/next_touch_time.py --runs {args.runs} --seed {args.seed} "
        f"--bytecode {args.bytecode}`  ",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; shared 2-core machine; "
        f"{seconds:.0f} s; load average {os.getloadavg()[0]:.2f} at the end.",
        "",
        f"Median of {args.runs} runs per row, each a new process, warm index cache; the four "
        "bundled `objects` as the library. CPU = user + system time of the process. "
        + (
            "Bytecode written by an untimed first run (as on a user's machine)."
            if args.bytecode == "warm"
            else "No bytecode for meshrec (PYTHONDONTWRITEBYTECODE as set)."
        ),
        "",
        "| run | CPU (s) | wall (s) | verdict |",
        "|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['what']} | {r['cpu']:.2f} | {r['wall']:.2f} | {r['verdict']} |")
    cmd = [r["cpu"] for r in rows[1:]]
    lines += ["", f"next-touch: median CPU {statistics.median(cmd):.2f} s, max {max(cmd):.2f} s."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=3, help="timed runs per touch")
    p.add_argument("--seed", type=int, default=3, help="simulated touches' and advice's seed")
    p.add_argument(
        "--bytecode",
        choices=("warm", "none"),
        default="warm",
        help="warm: the children write and reuse bytecode (a temporary PYTHONPYCACHEPREFIX), "
        "as on a user's machine; none: the environment as it is",
    )
    p.add_argument("--out", type=Path, default=None, help="Markdown report")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    rows = run(args.runs, args.seed, lambda s: print(s, flush=True), args.bytecode)
    text = report(rows, args, time.perf_counter() - t0)
    print(text)
    if args.out is not None:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
