"""Start-up costs, each in a fresh process (best of ``--repeats``): ``import dualpixel``,
``dualpixel.list_models()`` (under 0.5 s; headers only, no torch) and
``dualpixel --help``.

    .venv/bin/python benchmarks/bench_startup.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

CASES = {
    "import dualpixel": [sys.executable, "-c", "import dualpixel"],
    "list_models()": [sys.executable, "-c", "import dualpixel; dualpixel.list_models()"],
    "dualpixel --help": [str(Path(sys.executable).with_name("dualpixel")), "--help"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    base = None
    for name, command in CASES.items():
        best = float("inf")
        for _ in range(args.repeats):
            started = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            best = min(best, time.perf_counter() - started)
        base = base or best
        print(f"{name:<20} {best:6.3f} s   {best / base:5.2f}x import")


if __name__ == "__main__":
    main()
