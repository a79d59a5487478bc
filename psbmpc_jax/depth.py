"""Sequential depth of a JAX program: how many loop iterations it executes, per loop site.

>>> report = sequential_depth(functools.partial(solve, config=config), inputs, state, params, samples)
>>> print(report.table()); report.depth

On a GPU every trip of an XLA while loop costs at least a kernel launch and a synchronisation, however wide the
arrays: the trips are the machine-independent floor of the GPU latency, counted here on any backend.

Definition.  ``jax.make_jaxpr(fn)(*args, **kwargs)`` is traced and its closed jaxpr interpreted with the
concrete inputs:

* ``scan`` of length L with ``unroll`` u lowers (``jax._src.lax.control_flow.loops._scan_impl``) to a while
  loop of ``L // u`` trips, the remainder ``L % u`` unrolled inline; ``u == 0`` and the fully unrolled case
  (``u != 1``, ``L // u == 1``, ``L % u == 0``) give 0 trips (``unroll=True`` reaches the jaxpr as u = L).
* ``while`` (``while_loop``; ``fori_loop`` with traced bounds, with Python ints it is a ``scan``): the number of
  times its body runs for these inputs.
* ``cond`` / ``switch``: only the branch taken (its index evaluated concretely) counts.
* call-like primitives (``pjit``, ``closed_call``, ``custom_jvp_call``, ``custom_vjp_call``, ``checkpoint``,
  ... : any with a ``jaxpr`` / ``call_jaxpr`` / ``fun_jaxpr`` parameter) count what their inner jaxpr counts.
* everything else is evaluated (bound) as it is.

The **depth** is the sum of the trips of every loop execution, a loop nested in a loop body counted once per
run of that body (the total number of loop iterations executed, nested ones included); ``loop_executions`` is
the number of loop executions (a fully unrolled scan counts, with 0 trips).  Loops are reported per site (the
source line of the ``scan`` / ``while_loop`` call, relative to the package's parent folder; same place and kind
merged).

Evaluation.  Where a jaxpr's loop counts are static (no ``while`` inside, no ``cond`` whose branches differ in
their loops) they are computed from the jaxpr alone and its equations run together as one jitted chunk; a
``while`` whose body and predicate are static runs as one jitted while loop with an int32 counter added to its
carry (outputs and trips in one call); only loops whose bodies hold data-dependent loops are interpreted per
iteration in Python (recursively).  The outputs are the program's (``DepthReport.outputs``).
:func:`sequential_depth_only` computes no outputs: only the equations that feed a data-dependent loop or branch
run, the others are counted from the jaxpr alone (a program without data-dependent loops does not run at all).

Every argument given to :func:`sequential_depth` is traced: bind static ones first, e.g.
``functools.partial(solve, config=config)`` for a ``jax.jit`` function with ``static_argnames=("config",)``.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections import Counter
from typing import Any

import jax
import jax.extend.core as jcore
import jax.numpy as jnp
from jax import lax
from jax._src import source_info_util

#: Parameters of call-like primitives that hold the jaxpr they run.
CALL_PARAMS = ("jaxpr", "call_jaxpr", "fun_jaxpr")
#: Site paths are relative to the folder holding this package, or JAX's (for loops built inside JAX).
_ROOTS = tuple(os.path.dirname(os.path.dirname(os.path.abspath(f))) for f in (__file__, jax.__file__))


@dataclasses.dataclass(frozen=True)
class LoopSite:
    """One loop site: ``where`` (``"file:line (function)"``), ``kind`` (``"scan"``, ``"while"``, or ``"kernel"``: a
    Pallas kernel, one launch whose own loops run inside it, 0 trips), its ``executions``, the ``trips`` summed
    over them and the fewest / most per execution, and for scans the ``length`` and ``unroll`` (None where the
    merged executions differ, and for while loops)."""

    where: str
    kind: str
    executions: int
    trips: int
    min_trips: int
    max_trips: int
    length: int | None = None
    unroll: int | None = None


@dataclasses.dataclass(frozen=True)
class DepthReport:
    """Result of :func:`sequential_depth`: ``depth`` (loop trips executed in all), ``loop_executions``, the
    ``sites`` (most trips first) and the program's ``outputs`` (not part of :meth:`to_dict` nor of ``==``)."""

    depth: int
    loop_executions: int
    sites: tuple[LoopSite, ...]
    outputs: Any = dataclasses.field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict:
        return {"depth": self.depth, "loop_executions": self.loop_executions,
                "sites": [dataclasses.asdict(s) for s in self.sites]}

    def table(self) -> str:
        """A text table: one row per site, then the totals."""
        head = ("where", "kind", "length", "unroll", "executions", "trips", "trips/execution")
        rows = []
        for s in self.sites:
            per = f"{s.trips / s.executions:.4g}" + (f" ({s.min_trips}..{s.max_trips})"
                                                     if s.min_trips != s.max_trips else "")
            rows.append((s.where, s.kind, "-" if s.length is None else str(s.length),
                         "-" if s.unroll is None else str(s.unroll), str(s.executions), str(s.trips), per))
        rows.append(("total", "", "", "", str(self.loop_executions), str(self.depth), ""))
        w = [max(len(r[i]) for r in (head, *rows)) for i in range(len(head))]
        line = lambda r: "  ".join(c.ljust(w[i]) if i < 2 else c.rjust(w[i]) for i, c in enumerate(r))  # noqa: E731
        return "\n".join([line(head), "  ".join("-" * n for n in w), *map(line, rows)])


def scan_trips(length: int, unroll: int) -> int:
    """While-loop trips of a ``scan`` of ``length`` with ``unroll`` (the divmod of ``_scan_impl``)."""
    trips, rem = divmod(length, unroll) if unroll else (0, length)
    return 0 if unroll != 1 and trips == 1 and rem == 0 else trips


def _where(eqn) -> str:
    tb = eqn.source_info.traceback
    # the user's frame; else (a loop built inside JAX, e.g. searchsorted's, its traceback cut) the outermost kept
    frame = (source_info_util.user_frame(tb) or tb.frames[-1]) if tb is not None and tb.frames else None
    if frame is None:
        return source_info_util.summarize(eqn.source_info) or "<unknown>"
    path = os.path.abspath(frame.file_name)
    root = next((r for r in _ROOTS if path.startswith(r + os.sep)), None)
    line = getattr(frame, "start_line", None) or getattr(frame, "line_num", None)     # the name by JAX version
    return f"{os.path.relpath(path, root) if root else path}:{line} ({frame.function_name.replace('.<locals>.', '.')})"


def _bind(eqn, invals) -> list:
    with source_info_util.user_context(eqn.source_info.traceback), eqn.ctx.manager:
        out = eqn.primitive.bind(*invals, **eqn.primitive.get_bind_params(eqn.params))
    return list(out) if eqn.primitive.multiple_results else [out]


class _Analyser:
    """Caches (by object id; the traced jaxpr keeps every object alive) and the counts of one analysis.

    A *profile* is a Counter ``(where, kind, length, unroll, trips) -> executions`` of the loops one run of a
    jaxpr (or equation) executes, or None where that depends on the data."""

    def __init__(self):
        self.counts: Counter = Counter()
        self._cache: dict = {}

    def _memo(self, what, obj, make):
        key = (what, id(obj))
        return self._cache[key] if key in self._cache else self._cache.setdefault(key, make())

    def profile(self, jaxpr) -> Counter | None:
        def make() -> Counter | None:
            parts = [self.eqn_profile(e) for e in jaxpr.eqns]
            return None if any(p is None for p in parts) else _total(parts)
        return self._memo("profile", jaxpr, make)

    def eqn_profile(self, eqn) -> Counter | None:
        return self._memo("eqn", eqn, lambda: self._eqn_profile(eqn))

    def _eqn_profile(self, eqn) -> Counter | None:
        name, params = eqn.primitive.name, eqn.params
        if name == "while":
            return None
        if name == "scan":
            body = self.profile(params["jaxpr"].jaxpr)
            if body is None:
                return None
            length, unroll = int(params["length"]), int(params["unroll"])
            own = (_where(eqn), "scan", length, unroll, scan_trips(length, unroll))
            return Counter({own: 1}) + Counter({k: v * length for k, v in body.items()})
        if name == "pallas_call":       # one kernel launch: the loops inside run in registers, not as launches
            return Counter({(_where(eqn), "kernel", None, None, 0): 1})
        if name == "cond":
            branches = [self.profile(b.jaxpr) for b in params["branches"]]
            return branches[0] if all(b is not None and b == branches[0] for b in branches) else None
        inner = _inner(eqn)
        if inner is not None:
            return self.profile(inner[0])
        if any(self.profile(sub) != Counter() for sub in jcore.jaxprs_in_params(params)):
            raise ValueError(f"sequential_depth: primitive {name!r} ({_where(eqn)}) holds loops it cannot count; only "
                             f"scan, while, cond and call-like primitives (parameters {CALL_PARAMS}) are supported")
        return Counter()

    def plan(self, jaxpr, needed) -> tuple:
        """``(profile of the equations skipped, segments)`` to run a jaxpr for the outputs flagged in ``needed``
        (None: all).  An equation runs if dynamic (loop counts depending on the data), effectful, or feeding one
        that runs.  Segments: ``("chunk", fn, eqns, invars, outvars, profile)``, static equations run as one jitted
        call (a lone one bound as it is: fn None), or ``("eqn", eqn, needed outputs)``, a dynamic equation."""
        eqns, n = jaxpr.eqns, len(jaxpr.eqns)
        outs = [v for i, v in enumerate(jaxpr.outvars) if needed is None or needed[i]]
        last = {v: n for v in outs if not isinstance(v, jcore.Literal)}   # last use by an equation that runs
        runs = [False] * n
        out_needed: list[tuple[bool, ...]] = [()] * n       # every entry set below
        for i in range(n - 1, -1, -1):
            e = eqns[i]
            out_needed[i] = tuple(v in last for v in e.outvars)
            if self.eqn_profile(e) is None or e.effects or any(out_needed[i]):
                runs[i] = True
                for v in e.invars:
                    if not isinstance(v, jcore.Literal) and v not in last:
                        last[v] = i
        skipped = _total([self.eqn_profile(e) for e, r in zip(eqns, runs) if not r])
        segments: list[tuple] = []
        running = [i for i in range(n) if runs[i]]
        for dynamic, members in itertools.groupby(running, key=lambda i: self.eqn_profile(eqns[i]) is None):
            group = list(members)
            if dynamic:
                segments += [("eqn", eqns[i], None if all(out_needed[i]) else out_needed[i]) for i in group]
                continue
            chunk = [eqns[i] for i in group]
            inner = {v for e in chunk for v in e.outvars}      # SSA: defined before any use
            ins = list(dict.fromkeys(v for e in chunk for v in e.invars
                                     if not isinstance(v, jcore.Literal) and v not in inner))
            outs = [v for e in chunk for v in e.outvars if last.get(v, -1) > group[-1]]
            fn = None
            if len(chunk) > 1 or len(outs) < len(chunk[0].outvars):
                info = jcore.DebugInfo("sequential_depth", f"chunk of {len(chunk)} equations", None, None)
                effects = set().union(*(e.effects for e in chunk))
                fn = jax.jit(jcore.jaxpr_as_fun(jcore.ClosedJaxpr(jcore.Jaxpr([], ins, outs, chunk, effects,
                                                                              info), [])))
            segments.append(("chunk", fn, chunk, ins, outs, _total([self.eqn_profile(e) for e in chunk])))
        return skipped, segments

    def run(self, jaxpr, consts, args, needed: tuple | None = None) -> list:
        """The outputs of a jaxpr (None for those not ``needed``), counting its loops."""
        skipped, segments = self._memo(("plan", needed), jaxpr, lambda: self.plan(jaxpr, needed))
        self.counts.update(skipped)
        env = dict(zip([*jaxpr.constvars, *jaxpr.invars], [*consts, *args]))
        read = lambda v: v.val if isinstance(v, jcore.Literal) else env.get(v)  # noqa: E731
        for seg in segments:
            if seg[0] == "chunk":
                _, fn, eqns, ins, outs, profile = seg
                if fn is None:
                    outs, vals = eqns[0].outvars, _bind(eqns[0], [read(v) for v in eqns[0].invars])
                else:
                    vals = fn(*(env[v] for v in ins))
                self.counts.update(profile)
            else:
                _, eqn, out_needed = seg
                outs, vals = eqn.outvars, self.eval_eqn(eqn, [read(v) for v in eqn.invars], out_needed)
            env.update((v, x) for v, x in zip(outs, vals) if not isinstance(v, jcore.DropVar))
        return [read(v) for v in jaxpr.outvars]

    def eval_eqn(self, eqn, invals, needed: tuple | None = None) -> list:
        """Evaluate an equation whose loop counts depend on the data, counting its loops (``needed``: which
        outputs are wanted, None: all; loops compute all of theirs)."""
        name, params = eqn.primitive.name, eqn.params
        if name == "scan":
            return self._scan(eqn, invals)
        if name == "while":
            return self._while(eqn, invals)
        if name == "cond":
            branches = params["branches"]
            taken = branches[min(max(int(invals[0]), 0), len(branches) - 1)]
            profile = self.profile(taken.jaxpr)
            if profile is None:
                return self.run(taken.jaxpr, taken.consts, invals[1:], needed)
            self.counts.update(profile)
            return [None] * len(eqn.outvars) if needed is not None and not any(needed) else _bind(eqn, invals)
        inner = _inner(eqn)
        assert inner is not None, "call-like: eqn_profile refused the others"
        return self.run(inner[0], inner[1], invals, needed)

    def _scan(self, eqn, invals) -> list:
        p = eqn.params
        body, length, n_consts, n_carry = p["jaxpr"], int(p["length"]), p["num_consts"], p["num_carry"]
        consts, carry, xs = invals[:n_consts], invals[n_consts:n_consts + n_carry], invals[n_consts + n_carry:]
        ys: list = [None] * length
        for k in range(length):
            i = length - 1 - k if p["reverse"] else k
            out = self.run(body.jaxpr, body.consts, [*consts, *carry, *(x[i] for x in xs)])
            carry, ys[i] = out[:n_carry], out[n_carry:]
        stacked = [jnp.stack([jnp.asarray(y[j], a.dtype) for y in ys]) if length else jnp.zeros((0, *a.shape), a.dtype)
                   for j, a in enumerate(body.out_avals[n_carry:])]
        self.counts[(_where(eqn), "scan", length, int(p["unroll"]), scan_trips(length, int(p["unroll"])))] += 1
        return [*carry, *stacked]

    def _while(self, eqn, invals) -> list:
        p = eqn.params
        cond, body, nc, nb = p["cond_jaxpr"], p["body_jaxpr"], p["cond_nconsts"], p["body_nconsts"]
        cconsts, bconsts, carry = invals[:nc], invals[nc:nc + nb], invals[nc + nb:]
        pc, pb = self.profile(cond.jaxpr), self.profile(body.jaxpr)
        if pc is not None and pb is not None:
            carry, trips = self._memo("while", eqn, lambda: _counted_while(cond, body, nc, nb))(*invals)
            trips = int(trips)      # one host sync per loop execution
            for profile, n in ((pb, trips), (pc, trips + 1)):     # the predicate runs once more than the body
                self.counts.update({k: v * n for k, v in profile.items() if n})
        else:
            trips = 0
            while bool(self.run(cond.jaxpr, cond.consts, [*cconsts, *carry])[0]):
                carry = self.run(body.jaxpr, body.consts, [*bconsts, *carry])
                trips += 1
        self.counts[(_where(eqn), "while", None, None, trips)] += 1
        return list(carry)


def _total(profiles: list) -> Counter:
    """The sum of loop profiles that are all known (not None: static equations)."""
    total: Counter = Counter()
    for p in profiles:
        assert p is not None, "only static equations (a profile, not None) are summed"
        total += p
    return total


def _inner(eqn):
    """``(jaxpr, consts)`` a call-like equation runs on its own inputs, or None."""
    shapes = lambda vs: [getattr(v.aval, "shape", None) for v in vs]  # noqa: E731
    for name in CALL_PARAMS:
        sub = eqn.params.get(name)
        jaxpr, consts = (sub.jaxpr, sub.consts) if isinstance(sub, jcore.ClosedJaxpr) else (sub, [])
        # the same inputs (not so a shard_map's body over several devices: it sees per-shard shapes)
        if isinstance(jaxpr, jcore.Jaxpr) and len(jaxpr.constvars) == len(consts) and \
                shapes(jaxpr.invars) == shapes(eqn.invars):
            return jaxpr, consts
    return None


def _counted_while(cond, body, n_cond: int, n_body: int):
    """The while loop of ``cond``/``body`` jitted with an int32 trip counter: ``f(*invals) -> (carry, trips)``."""
    cond_fn, body_fn = jcore.jaxpr_as_fun(cond), jcore.jaxpr_as_fun(body)

    def counted(*invals):
        cconsts, bconsts, init = invals[:n_cond], invals[n_cond:n_cond + n_body], invals[n_cond + n_body:]
        trips, out = lax.while_loop(lambda s: cond_fn(*cconsts, *s[1])[0],
                                    lambda s: (s[0] + 1, tuple(body_fn(*bconsts, *s[1]))),
                                    (jnp.zeros((), jnp.int32), tuple(init)))
        return list(out), trips

    return jax.jit(counted)


def _report(counts: Counter, outputs) -> DepthReport:
    merged: dict = {}
    for (where, kind, length, unroll, trips), n in counts.items():
        merged.setdefault((where, kind), []).append((n, trips, length, unroll))
    one = lambda values: values.pop() if len(values) == 1 else None  # noqa: E731
    sites = [LoopSite(where, kind, sum(r[0] for r in runs), sum(r[0] * r[1] for r in runs),
                      min(r[1] for r in runs), max(r[1] for r in runs), one({r[2] for r in runs}),
                      one({r[3] for r in runs}))
             for (where, kind), runs in merged.items()]
    sites.sort(key=lambda s: (-s.trips, -s.executions, s.where, s.kind))
    return DepthReport(sum(s.trips for s in sites), sum(s.executions for s in sites), tuple(sites), outputs)


def _analyse(fn, args, kwargs, outputs: bool) -> DepthReport:
    if not callable(fn):
        raise ValueError(f"sequential_depth: fn must be callable, got {type(fn).__name__}")
    closed, out_shape = jax.make_jaxpr(fn, return_shape=True)(*args, **kwargs)
    leaves = jax.tree.leaves((args, kwargs))
    if len(leaves) != len(closed.jaxpr.invars):
        raise ValueError(f"sequential_depth: {len(leaves)} argument leaves but the traced program takes "
                         f"{len(closed.jaxpr.invars)} inputs; pass static arguments bound with functools.partial")
    analyser = _Analyser()
    raw = analyser.run(closed.jaxpr, closed.consts, leaves, None if outputs else (False,) * len(closed.out_avals))
    outs = [o if getattr(o, "dtype", None) == s.dtype else jnp.asarray(o, s.dtype)
            for o, s in zip(raw, jax.tree.leaves(out_shape))] if outputs else None
    return _report(analyser.counts, None if outs is None else jax.tree.unflatten(jax.tree.structure(out_shape), outs))


def sequential_depth(fn, *args, **kwargs) -> DepthReport:
    """Run ``fn(*args, **kwargs)`` once, counting the loop iterations it executes (module docstring); the report's
    ``outputs`` are ``fn``'s.  Every argument is traced: bind static ones first (``functools.partial``)."""
    return _analyse(fn, args, kwargs, outputs=True)


def sequential_depth_only(fn, *args, **kwargs) -> DepthReport:
    """:func:`sequential_depth` without the outputs (``outputs`` None): only what decides a data-dependent loop
    or branch is computed, the rest is counted from the jaxpr.  The same counts, often much faster."""
    return _analyse(fn, args, kwargs, outputs=False)


__all__ = ["sequential_depth", "sequential_depth_only", "DepthReport", "LoopSite", "scan_trips", "CALL_PARAMS"]
