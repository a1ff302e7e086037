"""Save and load learned skills; describe them for people.

Layout of a skills directory:
    skills.json          format version, environment name, types, predicates, config,
                         stats and every operator in readable form
    domain.pddl          the operators as a typed STRIPS PDDL domain (for reading, or
                         for any PDDL planner)
    <Op>.policy.npz      policy weights and scope dimensions
    <Op>.sampler.npz     sampler weights (absent for skills without subgoals)
A skill whose policy and sampler are an environment's given skill
(:mod:`bpns.learning.given`) has no weights: its entry names the given skill and the
parameter binding, and loading looks it up among the environment's given skills.

Predicates are classifiers (code), so they are not saved: loading binds the saved
predicate and type *names* to the environment's objects and refuses a mismatch.
The directory is written next to its destination and renamed into place, so a crash
never leaves a half-written skills directory behind.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import tempfile
import zipfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from bpns.atomic import (
    recover_directory,
    remove_stale_temporaries,
    replace_directory,
    temporary_prefix,
)
from bpns.errors import BpnsError
from bpns.learning.artifacts import checks
from bpns.learning.artifacts.pddl import domain_pddl
from bpns.learning.config import LearningConfig, MLPConfig
from bpns.learning.demo_checks import check_finite_arrays
from bpns.learning.given import BoundPolicy, BoundSampler, GivenSkill
from bpns.learning.pipeline import LearnedSkills, LearningStats, SkillStats
from bpns.learning.policies import LearnedPolicy
from bpns.learning.samplers import CurrentStateSampler, LearnedSampler
from bpns.nets.layers import LayerShapeError
from bpns.structs import LiftedAtom, Predicate, Skill, STRIPSOperator, Type, Variable

FORMAT = "bpns-skills"
# Version 2 records every setting of the config: a key missing from it was removed by
# hand and is refused. Version 1 directories, saved while settings were still being
# added, may lack the newer ones and load with the values they had before them.
VERSION = 2
SUPPORTED_VERSIONS = (1, 2)
INDEX = "skills.json"
DOMAIN = "domain.pddl"


class ArtifactError(BpnsError, ValueError):
    """A skills directory that cannot be loaded against the given environment."""


# ---------------------------------------------------------------------------------- save


def save_skills(
    skills: LearnedSkills,
    directory: str | os.PathLike,
    overwrite: bool = False,
    env_name: str | None = None,
    beside: Callable[[Path], object] | None = None,
) -> Path:
    """Write ``skills`` to ``directory`` atomically; returns the directory path.

    ``env_name`` is recorded so that tools can load the skills without being told which
    environment's predicates to bind them to. ``beside(d)`` writes more files (the
    baselines) into the new directory ``d`` before it replaces ``directory``, so the
    skills and what was learned with them replace the old ones together or not at all.
    """
    target = Path(directory)
    recover_directory(target)  # a save killed between its two renames
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target} exists; pass overwrite=True to replace it")
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(target)  # of a save that was killed
    tmp = Path(tempfile.mkdtemp(prefix=temporary_prefix(target), dir=target.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes 0700; skills are shared like any directory
    try:
        entries = []
        for skill in skills.skills:
            entries.append(_write_skill(skill, tmp))
        index = {
            "format": FORMAT,
            "version": VERSION,
            "env": env_name,
            "types": [
                {"name": t.name, "features": list(t.feature_names)} for t in sorted(skills.types)
            ],
            "predicates": [
                {"name": p.name, "types": [t.name for t in p.types]}
                for p in sorted(skills.predicates)
            ],
            "config": dataclasses.asdict(skills.config),
            "stats": None if skills.stats is None else dataclasses.asdict(skills.stats),
            "skills": entries,
        }
        (tmp / INDEX).write_text(json.dumps(index, indent=2) + "\n")
        (tmp / DOMAIN).write_text(
            domain_pddl(env_name or "learned", skills.types, skills.predicates, skills.operators)
        )
        if beside is not None:
            beside(tmp)
        replace_directory(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target


def _write_skill(skill: Skill, directory: Path) -> dict[str, Any]:
    op = skill.operator
    if isinstance(skill.policy, BoundPolicy):
        return {
            **_operator_json(skill),
            "horizon": skill.horizon,
            "policy": None,
            "sampler": None,
            "given": skill.policy.given.name,
            "binding": list(skill.policy.binding),
        }
    if not isinstance(skill.policy, LearnedPolicy):
        raise TypeError(f"{op.name}: only LearnedPolicy can be saved, got {type(skill.policy)}")
    policy_file = f"{op.name}.policy.npz"
    check_finite_arrays(skill.policy.to_arrays(), f"{op.name} policy")
    np.savez(directory / policy_file, **skill.policy.to_arrays())
    entry: dict[str, Any] = {
        **_operator_json(skill),
        "policy": policy_file,
        "horizon": skill.horizon,
    }
    if isinstance(skill.sampler, LearnedSampler):
        entry["sampler"] = f"{op.name}.sampler.npz"
        check_finite_arrays(skill.sampler.to_arrays(), f"{op.name} sampler")
        np.savez(directory / entry["sampler"], **skill.sampler.to_arrays())
    elif isinstance(skill.sampler, CurrentStateSampler):
        entry["sampler"] = None
    else:
        raise TypeError(f"{op.name}: cannot save a sampler of type {type(skill.sampler)}")
    return entry


def _operator_json(skill: Skill) -> dict[str, Any]:
    op = skill.operator
    return {
        "name": op.name,
        "parameters": [[v.name, v.type.name] for v in op.parameters],
        "preconditions": _atoms_json(op.preconditions),
        "add_effects": _atoms_json(op.add_effects),
        "delete_effects": _atoms_json(op.delete_effects),
        "order_key": op.order_key,
    }


def _atoms_json(atoms: Iterable[LiftedAtom]) -> list[list[Any]]:
    return [[a.predicate.name, [v.name for v in a.variables]] for a in sorted(atoms)]


# ---------------------------------------------------------------------------------- load


def saved_env_name(directory: str | os.PathLike) -> str | None:
    """The environment name recorded in a skills directory (None if not recorded)."""
    index = _read_index(Path(directory))
    name = index.get("env")
    return str(name) if name else None


def _read_index(directory: Path) -> dict[str, Any]:
    index_path = directory / INDEX
    if not os.path.lexists(directory):
        try:
            recover_directory(directory)  # a save killed between its two renames
        except OSError:
            pass
    if not index_path.exists():
        raise ArtifactError(f"{directory} is not a skills directory (no {INDEX})")
    try:
        path = checks.confined_file(directory, INDEX)
        index = checks.parse_index(checks.read_regular_file(path, checks.MAX_INDEX_BYTES))
    except (OSError, ValueError) as err:
        raise ArtifactError(f"{index_path}: not a readable skills index ({err})") from None
    if (
        not isinstance(index, dict)
        or index.get("format") != FORMAT
        or index.get("version") not in SUPPORTED_VERSIONS
        or isinstance(index.get("version"), bool)
    ):
        got = (index.get("format"), index.get("version")) if isinstance(index, dict) else None
        raise ArtifactError(
            f"{index_path}: unsupported format {got!r} (expected {FORMAT!r} version {VERSION})"
        )
    try:
        checks.check_index_schema(index)
    except ValueError as err:
        raise ArtifactError(f"{index_path}: damaged skills index: {err}") from None
    return index


def load_skills(
    directory: str | os.PathLike,
    predicates: Iterable[Predicate],
    types: Iterable[Type],
    given: Iterable[GivenSkill] = (),
) -> LearnedSkills:
    """Load skills saved by :func:`save_skills`, binding names to the given predicates
    and types (and given skills, by name). Raises :class:`ArtifactError` naming whatever
    does not match."""
    given_by_name = {g.name: g for g in given}
    directory = Path(directory)
    index = _read_index(directory)
    try:
        type_map = _bind_types(index["types"], types, directory)
        pred_map = _bind_predicates(index["predicates"], predicates, type_map, directory)
        skills = tuple(
            _read_skill(e, directory, pred_map, type_map, given_by_name) for e in index["skills"]
        )
        _refuse_stray_weights(directory, index)
        return LearnedSkills(
            skills=skills,
            predicates=frozenset(pred_map.values()),
            config=_config_from_json(index["config"], complete=index["version"] >= 2),
            stats=None
            if index.get("stats") is None
            else _stats_from_json(index["stats"], complete=index["version"] >= 2),
        )
    except ArtifactError:
        raise
    except (
        KeyError,
        IndexError,
        TypeError,
        ValueError,
        OSError,
        EOFError,
        RuntimeError,
        NotImplementedError,
        zipfile.BadZipFile,
        zipfile.LargeZipFile,
    ) as err:
        # a hand-edited index, a missing or truncated weights file ...
        raise ArtifactError(
            f"{directory}: damaged skills directory ({type(err).__name__}: {err})"
        ) from None


def _refuse_stray_weights(directory: Path, index: Mapping[str, Any]) -> None:
    """A ``<Op>.policy.npz`` or ``<Op>.sampler.npz`` that no skill names: the index and
    the weights disagree (a skill's entry removed by hand, or weights copied in), so
    which skills the directory holds is in doubt."""
    named = {e.get(k) for e in index["skills"] for k in ("policy", "sampler")}
    try:
        names = sorted(p.name for p in directory.iterdir())
    except OSError as err:
        raise ArtifactError(f"{directory}: cannot list the skills directory ({err})") from None
    for name in names:
        if name.endswith((".policy.npz", ".sampler.npz")) and name not in named:
            raise ArtifactError(
                f"{directory}: {name} is the weights of no skill in {INDEX} (edited by "
                "hand?); remove the file, or learn the skills again"
            )


def _bind_types(saved: list[dict], types: Iterable[Type], where: Path) -> dict[str, Type]:
    available = {t.name: t for t in types}
    out = {}
    for entry in saved:
        name, features = entry["name"], tuple(entry["features"])
        if name not in available:
            raise ArtifactError(
                f"skills in {where} use type {name!r}, which the environment does not have "
                f"(it has {sorted(available)})"
            )
        if available[name].feature_names != features:
            raise ArtifactError(
                f"skills in {where} expect type {name!r} with features {list(features)}, the "
                f"environment's has {list(available[name].feature_names)}"
            )
        out[name] = available[name]
    return out


def _bind_predicates(
    saved: list[dict], predicates: Iterable[Predicate], type_map: Mapping[str, Type], where: Path
) -> dict[str, Predicate]:
    available = {p.name: p for p in predicates}
    out = {}
    for entry in saved:
        name = entry["name"]
        if name not in available:
            raise ArtifactError(
                f"skills in {where} use predicate {name!r}, which the environment does not "
                f"provide (it provides {sorted(available)})"
            )
        pred = available[name]
        if [t.name for t in pred.types] != entry["types"] or any(
            type_map[t.name] != t for t in pred.types
        ):
            raise ArtifactError(
                f"skills in {where} expect predicate {name}{tuple(entry['types'])}, the "
                f"environment's is {name}{tuple(t.name for t in pred.types)}"
            )
        out[name] = pred
    return out


def _read_skill(
    entry: Mapping[str, Any],
    directory: Path,
    preds: Mapping[str, Predicate],
    types: Mapping[str, Type],
    given: Mapping[str, GivenSkill] | None = None,
) -> Skill:
    variables = {n: Variable(n, types[t]) for n, t in entry["parameters"]}

    def atoms(key: str) -> frozenset[LiftedAtom]:
        out = set()
        for pname, args in entry[key]:
            if pname not in preds:
                raise ArtifactError(f"operator {entry['name']} uses unknown predicate {pname!r}")
            out.add(LiftedAtom(preds[pname], tuple(variables[a] for a in args)))
        return frozenset(out)

    op = STRIPSOperator(
        name=entry["name"],
        parameters=tuple(variables[n] for n, _ in entry["parameters"]),
        preconditions=atoms("preconditions"),
        add_effects=atoms("add_effects"),
        delete_effects=atoms("delete_effects"),
        order_key=entry.get("order_key"),  # absent in directories of Op<k>-named skills
    )
    horizon = entry.get("horizon")
    if entry.get("given") is not None:
        g = (given or {}).get(entry["given"])
        if g is None:
            raise ArtifactError(
                f"{directory}: skill {entry['name']} uses the given skill {entry['given']!r}, "
                "which the environment does not declare"
            )
        binding = tuple(int(i) for i in entry["binding"])
        if len(binding) != len(g.signature.parameters) or any(
            g.signature.parameters[k].type != op.parameters[i].type for k, i in enumerate(binding)
        ):
            raise ArtifactError(
                f"{directory}: skill {entry['name']} binds the given skill {g.name} with "
                f"{binding}, which does not fit its signature"
            )
        return Skill(
            op,
            BoundPolicy(g, binding),
            BoundSampler(g, binding),
            None if horizon is None else int(horizon),
        )
    policy_path = checks.confined_file(directory, entry["policy"])
    policy = _from_arrays(LearnedPolicy, policy_path, checks.POLICY_KEYS)
    sampler: LearnedSampler | CurrentStateSampler
    if entry["sampler"] is None:
        sampler = CurrentStateSampler()
    else:
        sampler_path = checks.confined_file(directory, entry["sampler"])
        sampler = _from_arrays(LearnedSampler, sampler_path, checks.SAMPLER_KEYS)
    for dims in (policy.dims, getattr(sampler, "dims", policy.dims)):
        n = dims.num_objects
        if n is not None and not 1 <= n <= len(op.parameters):
            raise ArtifactError(f"{op.name}: scope of {n} objects, the operator has fewer")
        chosen = dims.objects
        if chosen is not None and (
            not chosen
            or len(set(chosen)) != len(chosen)
            or not all(0 <= i < len(op.parameters) for i in chosen)
        ):
            raise ArtifactError(
                f"{op.name}: scope objects {list(chosen)} are not distinct parameters of "
                f"an operator with {len(op.parameters)}"
            )
    scope = policy.dims.scope(op.parameters)
    checks.check_skill_arrays(
        policy,
        sampler if isinstance(sampler, LearnedSampler) else None,
        sum(v.type.dim for v in scope),
        op.name,
    )
    return Skill(op, policy, sampler, None if horizon is None else int(horizon))


def _from_arrays(cls: Any, path: Path, allowed: Any) -> Any:
    """``cls.from_arrays`` of the weights file ``path``; a missing array or a network
    whose shapes do not chain is named with its file (a bare KeyError said neither,
    and numpy's broadcast error named no layer)."""
    try:
        return cls.from_arrays(checks.read_npz(path, allowed))
    except KeyError as err:
        raise ValueError(f"{path.name} lacks the array {err.args[0]!r}") from None
    except LayerShapeError as err:
        raise ValueError(f"{path.name}: {err}") from None


def _config_from_json(d: Mapping[str, Any], complete: bool = True) -> LearningConfig:
    checks.check_json_fields(d, LearningConfig, "config", complete)
    nets = {k: _mlp_config(d[k], complete) for k in ("policy", "generator", "classifier")}
    fields = {f.name for f in dataclasses.fields(LearningConfig)}
    rest = {k: v for k, v in d.items() if k in fields and k not in nets}
    rest.setdefault("share_effect_data", False)  # skills saved before these existed
    rest.setdefault("linear_sampler_base", False)
    rest.setdefault("linear_policy_base", False)
    return LearningConfig(**rest, **nets)


def _mlp_config(d: Mapping[str, Any], complete: bool = True) -> MLPConfig:
    checks.check_json_fields(d, MLPConfig, "config network", complete)
    return MLPConfig(**{**d, "hidden_sizes": tuple(d["hidden_sizes"])})


def _stats_from_json(d: Mapping[str, Any], complete: bool = True) -> LearningStats:
    checks.check_json_fields(d, LearningStats, "stats", complete)
    for s in d["skills"]:
        checks.check_json_fields(s, SkillStats, "stats.skills", complete)
    return LearningStats(
        **{k: v for k, v in d.items() if k not in ("skills", "stage_seconds")},
        skills=tuple(SkillStats(**s) for s in d["skills"]),
        stage_seconds=tuple((str(k), float(v)) for k, v in d["stage_seconds"]),
    )


# ------------------------------------------------------------------------------ describe


def describe(skills: LearnedSkills) -> str:
    """A readable listing of the skills' operators (``bpns skills show``)."""
    counts = {s.name: s.num_segments for s in skills.stats.skills} if skills.stats else {}
    lines = [f"{len(skills.skills)} skills"]
    if skills.stats is not None:
        lines[0] += f" learned from {skills.stats.num_demos} demonstrations"
        lines.append(f"  ({skills.stats})")
    for skill in skills.skills:
        lines.append("")
        extra = []
        if skill.name in counts:
            extra.append(f"{counts[skill.name]} segments")
        if skill.horizon is not None:
            extra.append(f"horizon {skill.horizon}")
        if isinstance(skill.policy, BoundPolicy):
            extra.append(f"given skill {skill.policy.given.name}")
        if isinstance(skill.sampler, CurrentStateSampler):
            extra.append("no subgoals")
        elif isinstance(skill.sampler, LearnedSampler) and skill.sampler.classifier_params is None:
            extra.append("sampler without classifier")
        header = str(skill.operator)
        if extra:
            first, _, rest = header.partition("\n")
            header = f"{first}    [{', '.join(extra)}]\n{rest}"
        lines.append(header)
        if isinstance(skill.sampler, LearnedSampler) and skill.sampler.novelty is not None:
            lines.append(_starts(skill))
    used = [(mark, text) for mark, text in ANNOTATIONS if any(mark in line for line in lines)]
    if used:
        lines += ["", "What the annotations mean:"]
        lines += [f"  {mark:<28}{text}" for mark, text in used]
    return "\n".join(lines)


# Each annotation describe() may print and what it means, shown under the listing (only
# those it printed): a new user met "sampler without classifier" with no way to tell.
ANNOTATIONS = (
    ("segments", "demonstration segments the operator was learned from"),
    ("horizon", "steps its policy may run before the run counts as failed"),
    ("given skill", "the environment's own policy and sampler; nothing learned"),
    ("no subgoals", "its objects never changed: the subgoal is the current state"),
    ("sampler without classifier", "no negative examples: every drawn subgoal is tried"),
    (
        "starts with",
        "where the sampler samples (the starts shown, with a margin); it refuses elsewhere",
    ),
)


def _starts(skill: Skill) -> str:
    """The context a learned sampler accepts (samplers.Novelty), e.g.
    ``starts with: ?button0.x in [0.21, 0.74]``; outside it the sampler refuses."""
    sampler = skill.sampler
    novelty = sampler.novelty
    params = skill.operator.parameters
    names = [
        f"{params[i].name}.{f}"
        for i in sampler.dims.scope_indices(len(params))
        for f in params[i].type.feature_names
    ]
    ranges = [
        f"{names[sampler.dims.state_dims[j]]} in [{lo:.3g}, {hi:.3g}]"
        for j, lo, hi in zip(novelty.dims, novelty.low, novelty.high, strict=True)
    ]
    return "    starts with: " + (", ".join(ranges) if ranges else "(any context)")
