"""Did a refactor keep behaviour? Fingerprint demos, learned skills and eval outcomes.

    python scripts/refactor_check.py run OUT [--envs cover stick_button coffee] > before.json
    python scripts/refactor_check.py fingerprint OUT > after.json
    python scripts/refactor_check.py compare before.json after.json

``run`` collects demos, learns skills and evaluates them with fixed seeds through the CLI
(Cover: 30 demos, BPNS and the oracle on 4 eval tasks; the others: 10 demos, the oracle
on 4 eval tasks) into OUT/<env>/, then prints the fingerprint (the commands' own output
goes to stderr). Run it on the code before
and after a change and ``compare``: the demonstrations (every stored array), the learned
weights (by content, in the skills' order), the operators (without their names: a renamed
operator is the same operator) and, per eval task, solved / actions / samples / simulator
steps / failure reason / the skeleton must all be equal. Timings are not compared; a task
that hit its timeout on a loaded machine shows up as a difference in samples, so rerun
it alone (``bpns eval ... -n 4``) before calling it a change.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

DEMOS = {"cover": 30}
LEARNED_EVAL = {"cover": ["bpns", "oracle"]}


def bpns(*args: str) -> None:
    """One CLI command; its output goes to stderr so that stdout is the fingerprint."""
    subprocess.run([sys.executable, "-m", "bpns.cli", *args], check=True, stdout=sys.stderr)


def read_fingerprint(path: Path, parser: argparse.ArgumentParser) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        parser.error(f"{path}: not a fingerprint (the JSON `run` or `fingerprint` prints): {err}")


def run(out: Path, envs: list[str]) -> None:
    for env in envs:
        d = out / env
        d.mkdir(parents=True, exist_ok=True)
        n = str(DEMOS.get(env, 10))
        bpns("demos", "--env", env, "-n", n, "--seed", "3", "--workers", "1",
             "--out", str(d / "demos.h5"), "--overwrite")  # fmt: skip
        bpns("learn", str(d / "demos.h5"), "--out", str(d / "skills"), "--overwrite")
        approaches = LEARNED_EVAL.get(env, ["oracle"])
        bpns("eval", "--skills", str(d / "skills"), "--approach", *approaches, "-n", "4",
             "--timeout", "120", "--workers", "1", "--seed", "5", "--out", str(d / "eval"),
             "--overwrite")  # fmt: skip


def _h5(path: Path) -> str:
    h = hashlib.sha256()
    with h5py.File(path, "r") as f:

        def visit(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                h.update(name.encode())
                h.update(np.ascontiguousarray(obj[()]).tobytes())

        f.visititems(visit)
    return h.hexdigest()[:16]


def _skills(d: Path) -> tuple[dict, dict[str, str]]:
    index = json.loads((d / "skills.json").read_text())
    weights, ops, names = hashlib.sha256(), [], {}
    for e in index["skills"]:
        key = e.get("order_key") or e["name"]  # the learned index, whatever the name
        names[e["name"]] = key
        for file in (e.get("policy"), e.get("sampler")):
            if file:
                with np.load(d / file) as z:
                    for k in sorted(z.files):
                        weights.update(k.encode())
                        weights.update(z[k].tobytes())
        fields = ("parameters", "preconditions", "add_effects", "delete_effects", "horizon")
        ops.append(json.dumps([key, *(e.get(f) for f in fields)]))
    operators = hashlib.sha256("\n".join(ops).encode()).hexdigest()[:16]
    return {"weights": weights.hexdigest()[:16], "operators": operators}, names


def _index_named(step: str, names: dict[str, str]) -> str:
    head, _, rest = step.partition("(")
    return names.get(head, head) + "(" + rest


def fingerprint(out: Path) -> dict:
    result = {}
    for d in sorted(p for p in out.iterdir() if p.is_dir()):
        entry: dict = {"demos": _h5(d / "demos.h5")}
        names: dict[str, str] = {}
        if (d / "skills" / "skills.json").exists():
            entry["skills"], names = _skills(d / "skills")

        results = d / "eval" / "results.json"
        for report in json.loads(results.read_text()) if results.exists() else []:
            entry[report["approach"]] = [
                [
                    t["index"],
                    t["solved"],
                    t["num_actions"],
                    t["samples"],
                    t["sim_steps"],
                    t["reason"],
                    [_index_named(s, names) for s in t["skeleton"]],
                ]  # fmt: skip
                for t in report["tasks"]
            ]
        result[d.name] = entry
    return result


def compare(before: dict, after: dict) -> list[str]:
    diffs = []
    for env in sorted(set(before) | set(after)):
        a, b = before.get(env, {}), after.get(env, {})
        for key in sorted(set(a) | set(b)):
            if a.get(key) != b.get(key):
                diffs.append(f"{env} {key}: {a.get(key)} -> {b.get(key)}")
    return diffs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run")
    r.add_argument("out", type=Path)
    r.add_argument("--envs", nargs="+", default=["cover", "stick_button", "coffee"])
    f = sub.add_parser("fingerprint")
    f.add_argument("out", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "compare":
        diffs = compare(read_fingerprint(args.before, parser), read_fingerprint(args.after, parser))
        print("\n".join(diffs) if diffs else "identical: demos, weights, operators, outcomes")
        return 1 if diffs else 0
    if args.command == "run":
        run(args.out, args.envs)
    print(json.dumps(fingerprint(args.out), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
