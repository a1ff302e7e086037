"""How long does `bpns learn` take, loading included, in one process and on every core?

    python scripts/bench_learning.py ENV=DEMOS.h5 [ENV=DEMOS.h5 ...] [--limit 1000] \
        [--repeat 3] [--out docs/results/learning.md]

For each demonstrations file it runs ``bpns learn`` twice with the same seed, once with
``--workers 1`` and once with one worker per core, reads the times the command reports
("learned ... in X s (+Y s loading)"), checks that both runs saved the same weights
(every array of every ``.npz``, NaN where NaN), and writes a markdown table: the ratio
of the two totals is measured in the same run on the same machine. ``--repeat K`` runs
the every-core learning K times and reports the median total with the range (the
machine's timing varies from run to run).
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

LINE = re.compile(
    r"learned (\d+) skills from (\d+) demonstrations of \S+ in ([\d.]+) s \(\+([\d.]+) s loading\)"
)


def learn(demos: Path, out: Path, limit: int, workers: int) -> tuple[int, float, float]:
    """(demos used, learning seconds, loading seconds) of one `bpns learn`."""
    cmd = [sys.executable, "-m", "bpns.cli", "learn", str(demos), "--out", str(out)]
    cmd += ["--limit", str(limit), "--seed", "0", "--overwrite", "--workers", str(workers)]
    env = {**os.environ, "BPNS_PROGRESS": "0"}
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
    found = LINE.search(proc.stdout)
    if found is None:
        raise SystemExit(f"no timing line in the output of {' '.join(cmd)}:\n{proc.stdout}")
    return int(found.group(2)), float(found.group(3)), float(found.group(4))


def same_weights(a: Path, b: Path) -> bool:
    files = sorted(p.name for p in a.glob("*.npz"))
    if files != sorted(p.name for p in b.glob("*.npz")):
        return False
    for name in files:
        x, y = np.load(a / name), np.load(b / name)
        if set(x.files) != set(y.files):
            return False
        for k in x.files:
            if not np.array_equal(x[k], y[k], equal_nan=x[k].dtype.kind == "f"):
                return False
    return True


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", metavar="ENV=DEMOS.h5")
    p.add_argument("--limit", type=int, default=1000)
    p.add_argument("--repeat", type=int, default=1, help="every-core runs per file")
    p.add_argument("--out", type=Path, help="markdown file to write (default: print)")
    args = p.parse_args()
    cores = os.cpu_count() or 1
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for item in args.files:
            env, _, path = item.partition("=")
            one, many = Path(tmp) / f"{env}_1", Path(tmp) / f"{env}_n"
            n, learn1, load1 = learn(Path(path), one, args.limit, 1)
            runs = [learn(Path(path), many, args.limit, cores) for _ in range(max(1, args.repeat))]
            same = "yes" if same_weights(one, many) else "**NO**"
            totals = sorted(learnn + loadn for _, learnn, loadn in runs)
            median = float(np.median(totals))
            _, learnn, loadn = min(runs, key=lambda r: abs(r[1] + r[2] - median))
            spread = f" (range {totals[0]:.1f}-{totals[-1]:.1f})" if len(totals) > 1 else ""
            total1 = learn1 + load1
            rows.append(
                f"| {env} | {n} | {learn1:.1f} + {load1:.1f} = {total1:.1f} | "
                f"{learnn:.1f} + {loadn:.1f} = {median:.1f}{spread} | "
                f"{total1 / median:.2f} | {same} |"
            )
    command = "python scripts/bench_learning.py " + " ".join(sys.argv[1:])
    text = "\n".join(
        [
            "## Learning time (`scripts/bench_learning.py`)",
            "",
            f"Produced by `{command}` on {platform.node() or 'this machine'}: "
            f"{platform.machine()}, {cores} cores, Python {platform.python_version()}, "
            f"{time.strftime('%Y-%m-%d')}. `bpns learn` of the first {args.limit} "
            "demonstrations, seed 0, times as the command reports them (learning + loading "
            "the HDF5 file, seconds), in one process and with one worker per core; the "
            "last column checks that both saved the same weights"
            + (
                f"; every-core runs {args.repeat} times, the median total (learning + loading "
                "of the run nearest it) and the range."
                if args.repeat > 1
                else "."
            ),
            "",
            f"| Environment | Demos | 1 worker (s) | {cores} workers (s) | ratio | same weights |",
            "|---|---:|---:|---:|---:|---|",
            *rows,
            "",
        ]
    )
    if args.out is None:
        print(text)
    else:
        tmp_out = args.out.with_suffix(args.out.suffix + ".tmp")
        tmp_out.write_text(text)
        os.replace(tmp_out, args.out)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
