"""Campaign definitions: scenarios x methods x seeds x runs, validated strictly, resolved (every scenario file's
SHA-256, the package version and commit), hashed, and cut into tasks of at most ``chunk_runs`` runs.

A campaign file (YAML, every key below; unknown keys are errors)::

    name: river_encounters          # optional; default: the file's stem
    scenarios: [head_on, crossing_give_way, my_case.yaml]   # built-in names or paths (relative to this file)
    methods: [psbmpc, sbmpc]        # optional; default [null]: each scenario's own mpc.method
    seeds: [0, 1]                   # base seeds (>= 0), or one integer
    runs: 200                       # Monte Carlo runs per scenario x method x seed
    chunk_runs: 50                  # at most this many runs per task (default 50)
    duration_s: 60                  # optional: every scenario simulated for this long instead of its own duration_s
    batch: auto                     # auto | vmap | loop (as psbmpc-jax run --batch)
    trajectories: false             # true: every run's trajectories too (trajectories.parquet)

Run ``r`` of a seed is the same simulation whatever task it falls in (``simulate(..., run_start=...)``), so the
rows of a campaign do not depend on ``chunk_runs``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pathlib
import re

from ..checks import integer
from ..scenario_checks import MAX_RUNS

__all__ = ["CampaignDefinition", "Task", "DEFAULT_CHUNK_RUNS", "MAX_CAMPAIGN_RUNS", "load_definition",
           "definition_from_dict", "resolve", "tasks", "definition_hash", "differences", "load_task_scenario"]

#: Runs per task when the campaign does not say (a task is one ``simulate`` call).
DEFAULT_CHUNK_RUNS = 50
#: Most runs per scenario x method x seed (a campaign streams them to disk task by task).
MAX_CAMPAIGN_RUNS = 1_000_000
KEYS = ("name", "scenarios", "methods", "seeds", "runs", "chunk_runs", "duration_s", "batch", "trajectories")
BATCH_MODES = ("auto", "vmap", "loop")


@dataclasses.dataclass(frozen=True)
class CampaignDefinition:
    """A validated campaign (module docstring).  ``scenarios`` are as given (names or absolute paths);
    ``methods`` holds None for "the scenario's own method"."""

    name: str
    scenarios: tuple[str, ...]
    methods: tuple[str | None, ...]
    seeds: tuple[int, ...]
    runs: int
    chunk_runs: int = DEFAULT_CHUNK_RUNS
    duration_s: float | None = None
    batch: str = "auto"
    trajectories: bool = False


@dataclasses.dataclass(frozen=True)
class Task:
    """One ``simulate`` call of a campaign: runs ``[run_start, run_start + runs)`` of one scenario, method, seed."""

    task_id: str
    scenario: str            # as in the definition (name or path)
    scenario_name: str       # the scenario's name (its file's ``name``)
    method: str | None
    seed: int
    run_start: int
    runs: int

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def _where(source) -> str:
    return f"{source}: " if source else ""


def _str_list(value, field: str, source, *, allow_none: bool = False) -> tuple:
    if isinstance(value, (str, int)) or (allow_none and value is None):
        value = [value]
    if not isinstance(value, (list, tuple)) or not value:
        raise ValueError(f"{_where(source)}campaign field '{field}' must be a non-empty list, got {value!r}")
    out: list[str | None] = []
    for i, v in enumerate(value):
        if v is None and allow_none:
            out.append(None)
            continue
        if not isinstance(v, str) or not v.strip():
            raise ValueError(f"{_where(source)}campaign field '{field}[{i}]' must be a non-empty string"
                             f"{' or null' if allow_none else ''}, got {v!r}")
        out.append(v.strip())
    dup = sorted({str(v) for v in out if out.count(v) > 1})
    if dup:
        raise ValueError(f"{_where(source)}campaign field '{field}' lists {', '.join(dup)} more than once")
    return tuple(out)


def definition_from_dict(data: dict, *, base_dir=None, source=None, default_name: str = "campaign"
                         ) -> CampaignDefinition:
    """Validate a campaign mapping (module docstring); every error names the field (and ``source``).  Relative
    scenario paths are taken relative to ``base_dir``."""
    if not isinstance(data, dict):
        raise ValueError(f"{_where(source)}a campaign must be a mapping of {', '.join(KEYS)}, got "
                         f"{type(data).__name__}")
    unknown = sorted(set(map(str, data)) - set(KEYS))
    if unknown:
        raise ValueError(f"{_where(source)}unknown campaign field(s) {', '.join(unknown)}; allowed: {', '.join(KEYS)}")
    for req in ("scenarios", "seeds", "runs"):
        if data.get(req) is None:
            raise ValueError(f"{_where(source)}campaign field '{req}' is required")
    name = data.get("name", default_name)
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.-]{1,100}", name):
        raise ValueError(f"{_where(source)}campaign field 'name' must be 1-100 letters, digits, '_', '.' or '-', "
                         f"got {name!r}")
    scenarios = []
    for s in _str_list(data["scenarios"], "scenarios", source):
        if s.lower().endswith((".yaml", ".yml")) or "/" in s or os.sep in s:
            p = pathlib.Path(s).expanduser()
            if not p.is_absolute() and base_dir is not None:
                p = pathlib.Path(base_dir) / p
            s = str(p.resolve())
        scenarios.append(s)
    methods = _str_list(data.get("methods", [None]), "methods", source, allow_none=True)
    seeds = data["seeds"]
    seeds = [seeds] if isinstance(seeds, int) and not isinstance(seeds, bool) else seeds
    if not isinstance(seeds, (list, tuple)) or not seeds:
        raise ValueError(f"{_where(source)}campaign field 'seeds' must be an integer or a non-empty list of "
                         f"integers >= 0, got {seeds!r}")
    seeds = tuple(integer(v, f"{_where(source)}campaign field 'seeds[{i}]'", ge=0, le=2 ** 32 - 1)
                  for i, v in enumerate(seeds))
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"{_where(source)}campaign field 'seeds' lists a seed more than once: {list(seeds)}")
    runs = integer(data["runs"], f"{_where(source)}campaign field 'runs'", ge=1, le=MAX_CAMPAIGN_RUNS)
    chunk = integer(data.get("chunk_runs", DEFAULT_CHUNK_RUNS), f"{_where(source)}campaign field 'chunk_runs'",
                    ge=1, le=MAX_RUNS)
    duration = data.get("duration_s")
    if duration is not None:
        if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not duration > 0 \
                or duration == float("inf"):
            raise ValueError(f"{_where(source)}campaign field 'duration_s' must be a number > 0 [s], got "
                             f"{duration!r}")
        duration = float(duration)
    batch = data.get("batch", "auto")
    if batch not in BATCH_MODES:
        raise ValueError(f"{_where(source)}campaign field 'batch' must be one of {', '.join(BATCH_MODES)}, got "
                         f"{batch!r}")
    traj = data.get("trajectories", False)
    if not isinstance(traj, bool):
        raise ValueError(f"{_where(source)}campaign field 'trajectories' must be true or false, got {traj!r}")
    return CampaignDefinition(name=name, scenarios=tuple(scenarios), methods=methods, seeds=seeds, runs=runs,
                              chunk_runs=chunk, duration_s=duration, batch=batch, trajectories=traj)


def load_definition(path, overrides: dict | None = None) -> CampaignDefinition:
    """Read and validate the campaign file ``path``; ``overrides`` (e.g. from command-line flags) replace its
    fields before validation."""
    import yaml

    from ..scenario.load import read_utf8

    p = pathlib.Path(path).expanduser()
    if not p.is_file():
        raise FileNotFoundError(f"campaign file not found: {p}")
    try:
        data = yaml.safe_load(read_utf8(p, "campaign file"))
    except yaml.YAMLError as exc:
        raise ValueError(f"{p}: not valid YAML ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{p}: a campaign file must hold a mapping of {', '.join(KEYS)}, got {type(data).__name__}")
    data.update({k: v for k, v in (overrides or {}).items() if v is not None})
    return definition_from_dict(data, base_dir=p.parent, source=p, default_name=re.sub(r"[^A-Za-z0-9_.-]", "_",
                                                                                         p.stem)[:100] or "campaign")


def scenario_path(item: str) -> pathlib.Path:
    """The file of a scenario given by name or path."""
    from ..scenario.load import builtin_path

    if item.lower().endswith((".yaml", ".yml")) or "/" in item or os.sep in item:
        return pathlib.Path(item)
    return builtin_path(item)


#: How a campaign's fields are named when loading a scenario refuses them.
RUNS_SETTING, DURATION_SETTING = "campaign chunk_runs", "campaign field 'duration_s'"


def load_task_scenario(item: str, method: str | None, runs: int, duration_s: float | None):
    """The scenario ``item`` as a task of the campaign simulates it: ``method`` (None: the file's), ``runs`` runs
    and the campaign's ``duration_s`` (None: the file's) -- both checked at load, a refusal naming the campaign's
    field (:func:`psbmpc_jax.scenario.load_scenario`), the duration recorded in ``Scenario.overrides``."""
    from ..scenario import load_scenario

    return load_scenario(item, method=method, runs=runs, runs_setting=RUNS_SETTING, duration_s=duration_s,
                         duration_setting=DURATION_SETTING)


def resolve(defn: CampaignDefinition) -> dict:
    """The resolved definition that a campaign folder stores and compares: the definition's fields, every
    scenario's name, file and SHA-256 (each loaded once with each method, so a bad scenario or method is
    refused before anything runs), and the package version and commit."""
    from .. import __version__
    from ..provenance import commit

    scenarios = []
    for item in defn.scenarios:
        path = scenario_path(item)
        names: set[str] = set()
        effective: dict[str, str | None] = {}
        for m in defn.methods:
            try:                        # as a task loads it: its runs, the campaign's duration
                sc = load_task_scenario(item, m, min(defn.chunk_runs, defn.runs), defn.duration_s)
            except FileNotFoundError as exc:
                raise ValueError(f"campaign field 'scenarios': {exc}") from None
            except ValueError as exc:
                raise ValueError(f"campaign scenario {item!r}" + (f" with method {m!r}" if m else "") +
                                 f": {exc}") from None
            names.add(sc.name)
            if sc.mpc.method in effective:
                raise ValueError(f"campaign field 'methods': {effective[sc.mpc.method]!r} and {m!r} both run "
                                 f"{sc.mpc.method} on scenario {item!r} (null means the scenario's own method); "
                                 f"give each method once")
            effective[sc.mpc.method] = m
        scenarios.append({"item": item, "name": names.pop(), "file": str(path),
                          "sha256": hashlib.sha256(path.read_bytes()).hexdigest()})
    dup = sorted({s["name"] for s in scenarios if [t["name"] for t in scenarios].count(s["name"]) > 1})
    if dup:
        raise ValueError(f"campaign field 'scenarios': two entries are scenarios named {', '.join(dup)}; the rows "
                         f"could not be told apart (give the files different names)")
    fields = dataclasses.asdict(defn)
    fields.update(scenarios=scenarios, methods=list(defn.methods), seeds=list(defn.seeds))
    return {"definition": fields, "package": {"version": __version__, "commit": commit()}}


def definition_hash(resolved: dict) -> str:
    """SHA-256 of the resolved definition (canonical JSON)."""
    return hashlib.sha256(json.dumps(resolved, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def differences(old: dict, new: dict, prefix: str = "") -> list[str]:
    """What differs between two resolved definitions, one line per field (``definition.runs: 200 -> 400``)."""
    out = []
    for k in sorted(set(old) | set(new)):
        a, b = old.get(k, "<absent>"), new.get(k, "<absent>")
        if isinstance(a, dict) and isinstance(b, dict):
            out += differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k}: {json.dumps(a)} -> {json.dumps(b)}")
    return out


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]", "_", text)


def tasks(resolved: dict) -> list[Task]:
    """The tasks of a resolved definition: for each scenario, method and seed, its runs cut into consecutive
    chunks of at most ``chunk_runs``.  Task ids are stable and name what they hold:
    ``<scenario>__<method>__s<seed>__r<first>-<last+1>``."""
    d = resolved["definition"]
    out = []
    width = len(str(d["runs"]))
    for sc in d["scenarios"]:
        for m in d["methods"]:
            for seed in d["seeds"]:
                for a in range(0, d["runs"], d["chunk_runs"]):
                    n = min(d["chunk_runs"], d["runs"] - a)
                    tid = (f"{_slug(sc['name'])}__{_slug(m) if m else 'file'}__s{seed}__"
                           f"r{a:0{width}d}-{a + n:0{width}d}")
                    out.append(Task(tid, sc["item"], sc["name"], m, seed, a, n))
    return out
