"""Loading demonstrations, against raw HDF5 reads of the same arrays, in one run.

    python scripts/bench_loading.py DEMOS.h5 [DEMOS.h5 ...] [--limit 1000] [--repeat 3]
    python scripts/bench_loading.py ... --section docs/results/loading.md

For each file, the first ``--limit`` demonstrations are loaded three ways, best of
``--repeat``:

- raw: h5py reads every demo's actions, features and flat states into numpy (no checks,
  no objects): the floor any loader pays;
- features only: ``iter_demonstrations(features_only=True)``, what ``bpns learn`` and the
  sweep's skills cells use (checked arrays, objects, states without simulator states);
- full: the default, as replay and rendering use it (each demo's MJCF scene compiled,
  its first flat state loaded to check the size, a SimState per state).

``--section`` writes a docs/RESULTS.md section (rebuild the file with
``python scripts/make_results.py --assemble-only``).
"""

from __future__ import annotations

import argparse
import platform
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path

import h5py

from bpns.data.datasets import count_demonstrations, iter_demonstrations
from bpns.env.registry import make_environment


def raw_read(path: Path, n: int) -> int:
    """Every array of the first ``n`` demos read into memory; returns the states read."""
    states = 0
    with h5py.File(path, "r") as f:
        data = f["data"]
        for i in range(n):
            g = data[f"demo_{i}"]
            g["actions"][()]
            states += len(g["states"][()])
            for name in g["features"]:
                g["features"][name][()]
    return states


def best_of(repeat: int, run: Callable[[], object]) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return min(times)


def measure(path: Path, limit: int, repeat: int) -> dict[str, object]:
    with h5py.File(path, "r") as f:
        env_name = f.attrs["env"]
    env = make_environment(str(env_name))
    n = min(limit, count_demonstrations(path))
    states = raw_read(path, n)  # also warms the OS file cache for every variant
    raw = best_of(repeat, lambda: raw_read(path, n))
    light = best_of(
        repeat, lambda: list(iter_demonstrations(path, env, range(n), features_only=True))
    )
    full = best_of(repeat, lambda: list(iter_demonstrations(path, env, range(n))))
    return {"env": env.name, "demos": n, "states": states, "raw": raw, "light": light, "full": full}


def table(rows: list[dict[str, object]]) -> list[str]:
    lines = [
        "| Environment | Demos | States | Raw HDF5 reads (s) | Features only (s) | "
        "Full (s) | Features only / raw | Full / raw | Full / features only |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        raw, light, full = float(r["raw"]), float(r["light"]), float(r["full"])  # type: ignore[arg-type]
        lines.append(
            f"| {r['env']} | {r['demos']} | {r['states']} | {raw:.2f} | {light:.2f} | "
            f"{full:.2f} | {light / raw:.1f} | {full / raw:.1f} | {full / light:.1f} |"
        )
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="+", type=Path, help="demonstration files (bpns demos)")
    parser.add_argument("--limit", type=int, default=1000, help="demos loaded per file")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs")
    parser.add_argument("--section", type=Path, help="write a docs/RESULTS.md section here")
    args = parser.parse_args()
    missing = [str(p) for p in args.files if not p.is_file()]
    if missing:
        parser.error(f"no such demonstration file: {', '.join(missing)}")
    if args.limit < 1 or args.repeat < 1:
        parser.error("--limit and --repeat must be >= 1")
    rows = [measure(p, args.limit, args.repeat) for p in args.files]
    lines = table(rows)
    print("\n".join(lines))
    if args.section:
        command = "python " + " ".join(shlex.quote(a) for a in sys.argv)
        text = [
            "## Loading demonstrations",
            "",
            f"Produced by `{command}` on {platform.node()}: {platform.machine()}, Python "
            f"{platform.python_version()}, {time.strftime('%Y-%m-%d')}. Best of "
            f"{args.repeat} runs each, one process, the file in the OS cache.",
            "",
            "Raw = h5py reads of every array, no checks and no objects (the floor); features "
            "only = what `bpns learn` and the sweeps' skills cells load (checked arrays, "
            "objects, states without simulator states); full = what replay and rendering "
            "load (each demo's MJCF scene compiled, a simulator state per state). Any "
            "`bpns demos` file can be measured; the sweeps keep theirs under "
            "`outputs/experiments/<sweep>/artifacts/demos/`. Learning from 1000 "
            "demonstrations used to pay the full column.",
            "",
            *lines,
            "",
        ]
        tmp = args.section.with_suffix(".md.tmp")
        tmp.write_text("\n".join(text))
        tmp.replace(args.section)
        print(f"wrote {args.section}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
