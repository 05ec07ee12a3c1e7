"""Start-up: how long ``monovo --help`` and friends take, and what they import.

    python -m benchmarks.startup              # 20 runs of each command
    python -m benchmarks.startup --runs 50

Each command runs as a fresh process (``python -m monovo_cli ...``, the interpreter of this
environment); the table gives the median, minimum and maximum wall time, a bare
``python -c pass`` beside them for the interpreter's own start, and whether numpy or OpenCV
was loaded (checked in a separate run that lists ``sys.modules`` at exit).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

from benchmarks.common import load, machine

COMMANDS = (["--help"], ["--version"], ["track", "--help"], ["batch", "--help"],
            ["synth", "--help"])
PROBE = ("import runpy, sys; sys.argv = ['monovo'] + sys.argv[1:]\n"
         "try:\n    runpy.run_module('monovo_cli', run_name='__main__')\n"
         "except SystemExit:\n    pass\n"
         "print('numpy' in sys.modules, 'cv2' in sys.modules, file=sys.stderr)")


def timed(argv: list[str], runs: int) -> list[float]:
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        out.append(time.perf_counter() - t0)
    return out


def heavy_imports(args: list[str]) -> str:
    r = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True)
    numpy, cv2 = r.stderr.split()[-2:]
    return "yes" if "True" in (numpy, cv2) else "no"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=20)
    args = ap.parse_args()
    print(f"Machine: {machine()}; {load()} at the start\n")
    rows = []
    base = timed([sys.executable, "-c", "pass"], args.runs)
    rows.append(("python -c pass", base, "-"))
    for cmd in COMMANDS:
        t = timed([sys.executable, "-m", "monovo_cli", *cmd], args.runs)
        rows.append(("monovo " + " ".join(cmd), t, heavy_imports(cmd)))
    print("| command | median (s) | min | max | numpy or OpenCV loaded |")
    print("| --- | --- | --- | --- | --- |")
    for name, t, heavy in rows:
        print(f"| `{name}` | {statistics.median(t):.3f} | {min(t):.3f} | {max(t):.3f} | {heavy} |")
    print(f"\n({load()} at the end.)")


if __name__ == "__main__":
    main()
