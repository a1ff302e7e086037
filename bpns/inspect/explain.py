"""A failed task's explanation (``TaskOutcome.explanation``: the abstract plans tried,
each step's samples and why they failed) as readable lines, for recordings and the
report."""

from __future__ import annotations

from collections.abc import Mapping


def explanation_lines(explanation: Mapping | None) -> list[str]:
    """Markdown-friendly lines: failed samples by reason, then each abstract plan tried
    with, per step, how many samples reached it and how many failed and why."""
    if not explanation:
        return ["no explanation recorded (evaluate with `bpns eval --out` to keep one)"]
    e = explanation
    lines = []
    if e.get("failures"):
        failures = ", ".join(f"{r} {n}" for r, n in sorted(e["failures"].items()))
        lines.append(f"failed samples by reason: {failures}")
    if "abstract_plans" in e:
        shown = len(e.get("skeletons", ()))
        lines.append(
            f"{e['abstract_plans']} abstract plans tried"
            + (f" (the first {shown} below)" if e["abstract_plans"] > shown else "")
        )
    for k, skeleton in enumerate(e.get("skeletons", ())):
        lines.append(f"plan {k + 1} ({skeleton.get('reason') or 'refined'}):")
        for step in skeleton.get("steps", ()):
            failed = ", ".join(f"{r} {n}" for r, n in sorted(step.get("failures", {}).items()))
            reached = step.get("successes", 0)
            if not reached and not failed:
                lines.append(f"    {step.get('step')}: not tried (or reused)")
                continue
            lines.append(
                f"    {step.get('step')}: {reached} samples reached it"
                + (f"; failed: {failed}" if failed else "")
            )
    if "executed" in e:
        lines.append(f"executed: {', '.join(e['executed']) or '(nothing)'}")
        if e.get("failed_step"):
            lines.append(f"failed at: {e['failed_step']}")
    return lines


def explanation_markdown(explanation: Mapping | None) -> str:
    body = "\n".join(
        f"- {line.strip()}" if not line.startswith("    ") else f"    - {line.strip()}"
        for line in explanation_lines(explanation)
    )
    return "### what the planner tried\n\n" + body + "\n"
