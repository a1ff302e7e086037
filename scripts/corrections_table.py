"""The table of docs/WORLDS.md "Corrections from the oracle": per variant and world, solved
tasks per seed, pooled with a Wilson 95 % interval, replans per task and the median
time of solved tasks, from `bpns eval --out DIR` results.

python scripts/corrections_table.py ROOT --seeds 91 92 93

reads ROOT/{prefix}ev_{variant}_{seed}_{world}/results.json (variant base, corr, rel; world
nominal, moderate, hard): the directories `bpns eval ... --out` wrote.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

from bpns.evaluation.intervals import wilson_interval

VARIANTS = {
    "base": "plain skills",
    "corr": "`--corrections moderate --keep-demonstrator-labels`",
    "rel": "`--corrections moderate` (the default: the oracle relabels the demonstrations)",
}
WORLDS = ("nominal", "moderate", "hard")


def tasks(root: Path, variant: str, seed: int, world: str, prefix: str = "") -> list[dict] | None:
    path = root / f"{prefix}ev_{variant}_{seed}_{world}" / "results.json"
    if not path.exists():
        return None
    (row,) = json.loads(path.read_text())
    return row["tasks"]


def cell(root: Path, variant: str, seeds: list[int], world: str, prefix: str = "") -> str:
    per_seed = [tasks(root, variant, s, world, prefix) for s in seeds]
    if any(t is None for t in per_seed):
        return "–"
    solved = [sum(t["solved"] for t in ts) for ts in per_seed]
    every = [t for ts in per_seed for t in ts]
    k, n = sum(solved), len(every)
    low, high = wilson_interval(k, n)
    replans = statistics.mean(t.get("replans") or 0 for t in every)
    times = [t["seconds"] for t in every if t["solved"]]
    median = statistics.median(times) if times else float("nan")
    counts = ", ".join(map(str, solved))
    return (
        f"{counts}: {k}/{n} [{100 * low:.1f}, {100 * high:.1f}]; "
        f"{replans:.1f} replans, {median:.1f} s"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", type=Path)
    ap.add_argument("--seeds", type=int, nargs="+", required=True)
    ap.add_argument("--prefix", default="", help="of the result directories' names")
    ap.add_argument("--label", default="Coffee BPNS (250)", help="the table's first header")
    args = ap.parse_args()
    seeds = "-".join(map(str, (args.seeds[0], args.seeds[-1])))
    print(f"| {args.label}, seeds {seeds} × 20 | " + " | ".join(WORLDS) + " |")
    print("|---|" + "---:|" * len(WORLDS))
    for variant, label in VARIANTS.items():
        cells = [cell(args.root, variant, args.seeds, w, args.prefix) for w in WORLDS]
        print(f"| {label} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
