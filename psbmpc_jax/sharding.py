"""Multi-device solves with ``jax.shard_map``: one solve's behaviour axis, or a batch of solves' runs axis, split
over several local devices.

Two splits, one or the other per solve (never both: a batch split over its runs gives each device whole solves,
each with its whole behaviour table):

* :func:`solve_sharded` -- **one solve, its behaviour table split** (section "Behaviour axis").  For one large
  solve (a planner call of your own); the simulator does not use it.
* :func:`solve_batch` -- **a batch of solves, split along the batch** (the closed-loop simulator's Monte Carlo
  runs: :func:`psbmpc_jax.sim.simulate` with ``devices=``; section "Runs axis").

Behaviour axis
--------------

This mirrors splitting the CUDA grid of the original PSB-MPC over several GPUs: every control behaviour
is independent of the others (kernel 1 rolls out one own-ship trajectory per behaviour, kernel 2 scores it
against every obstacle scenario and polygon), so the B behaviours are cut into equal contiguous slices,
one per device, and each device runs the ordinary single-device search
(:func:`psbmpc_jax.evaluate.evaluate_arrays`) on its slice; the selection is the single-device one
(:func:`psbmpc_jax.solve.select`).

Layout (a 1-D :class:`jax.sharding.Mesh` with one axis named ``"b"``, D devices):

* ``inputs.behaviours`` (``offsets [B, n_M, 2]``, ``mask [B]``) are split along B (``PartitionSpec("b")``).  When B is
  not a multiple of D, B is padded on the host up to ``Bp = ceil(B / D) * D`` with masked copies of
  behaviour 0 (masked behaviours get cost +inf inside the evaluator); the padding is cut off again, so the
  result has exactly the shapes :func:`~psbmpc_jax.evaluate.evaluate` returns.
* Everything else (own-ship, obstacles, polygons, distance grid, parameters, random-number table) is
  replicated.  In particular the obstacle prediction (scenario rollouts and covariances) is recomputed on
  every device: it is O(O·S·T) work, tiny next to the O(B·O·S·T) collision kernel, and replicating it
  avoids any cross-device communication inside the evaluator.
* Per-behaviour outputs (``total [B]``, every term's cost and details — by default ``C, mu [B, O, S]`` and
  ``so_j [B, P]`` —, and the own-ship trajectories, which are time-major ``[T, B]`` so B is their axis 1)
  are concatenated along B (their specs are derived from the terms' outputs); the replicated outputs
  (``obstacles``, ``obs_cov``) come from one device; counters (``n_pc_blocks``) are summed over the devices; ``best`` is the global argmin over the concatenated totals (first index on ties, as
  ``jnp.argmin``) and ``best_offsets = behaviours[best]``.

The whole thing (shard_map + the final reduction) is jitted once per (config, device set) and, through
``jax.jit``'s own cache, once per input shapes/dtypes; values never recompile.

Results equal the single-device :func:`~psbmpc_jax.solve.solve` per behaviour (every behaviour's
costs are computed by the same code from the same inputs; in float64 they agree to the last bits or
within rounding).  One difference: ``n_pc_blocks`` counts the work actually done, so when B had to be
padded to a multiple of D the extra masked copies of behaviour 0 add their collision-probability blocks
(exactly the single-device count when D divides B).

Runs axis
---------

The simulator's vmapped call (``batch="vmap"``) solves every run and ship of one MPC update at once: a leading
batch axis of n independent solves, runs major (whole runs stay together).  :func:`solve_batch` cuts it into D
equal contiguous slices, one per device (a 1-D mesh with one axis named ``"runs"``), and each device runs the
program of the single-device call (``vmap`` of :func:`psbmpc_jax.solve.solve_arrays`) on its slice; nothing
passes between the devices.  The per-solve inputs (own-ship, obstacles) and the planner states are split
(``PartitionSpec("runs")``); the chart, grid, behaviour table, parameters and sample table are replicated.  When
n is not a multiple of D the batch is padded on the host up to ``ceil(n / D) * D`` with copies of solve 0 (a
real situation, so the padding computes nothing unusual); the padded solves' outputs are cut off inside the
jitted call, so every output has exactly the single-device shapes ``[n, ...]`` and no padded solve reaches a
result.  Each solve is computed by the same code from the same inputs as on one device, and its sums over
obstacles, scenarios and quadrature nodes are added in a fixed order (:func:`psbmpc_jax.numerics.ordered_sum`;
XLA:CPU picks ``jnp.sum``'s order by the whole batch's shape), so the split results equal one device's bit for
bit (``tests/test_sharding_runs.py``).
"""

from __future__ import annotations

from functools import lru_cache, partial
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from .costs.base import check_terms
from .evaluate import DEFAULT_TERMS, Evaluation, evaluate_arrays
from .ownship import Trajectory
from .packing import SHARED_AXES, SolveInputs, pad_behaviours
from .params import Params, PlannerConfig
from .solve import PlannerState, select, solve_arrays

AXIS = "b"
#: The mesh axis of the runs split (:func:`solve_batch`).
RUNS_AXIS = "runs"


def check_devices(devices: Sequence | None) -> tuple:
    """The device set to shard over (default ``jax.local_devices()``), validated, as a tuple."""
    if devices is None:
        devices = jax.local_devices()
    try:
        devices = tuple(devices)
    except TypeError:
        raise ValueError(f"devices must be a sequence of jax devices, got {type(devices).__name__}") from None
    if not devices:
        raise ValueError("devices must hold at least one device, got an empty list")
    platforms = sorted({str(getattr(d, "platform", "<not a device>")) for d in devices})
    if len(platforms) > 1:
        raise ValueError(f"devices must all be of one platform, got a mix of {platforms}")
    for d in devices:
        if not isinstance(d, jax.Device):
            raise ValueError(f"devices must be jax devices (e.g. from jax.local_devices()), got {d!r}")
    if len(set(devices)) != len(devices):
        raise ValueError(f"devices must be distinct, got {list(devices)}")
    return devices


def _split_spec(tree, spec):
    return jax.tree.map(lambda _: spec, tree)


@lru_cache(maxsize=32)
def _sharded_fn(config: PlannerConfig, devices: tuple):
    """Jitted ``(inputs, state, params, samples, terms, n_b) -> (plan, state, Evaluation)`` for one config
    and device set (jit's own cache keys the input shapes and the term classes).

    ``inputs`` already holds the padded behaviour axis ``Bp`` (a multiple of ``len(devices)``); the
    output is cut back to the first ``n_b`` behaviours (``n_b`` static)."""
    mesh = Mesh(np.array(devices, dtype=object), (AXIS,))
    rep = P()

    def local(inputs: SolveInputs, last_offsets, params: Params, samples, terms):
        ev = evaluate_arrays(inputs, last_offsets, params, samples, config, terms)
        # replicated outputs and the counters get a leading per-device axis: [D, ...] after the map
        per_dev = lambda tree: jax.tree.map(lambda a: a[None], tree)
        return (ev.total, ev.costs, ev.details, ev.own, per_dev(ev.obstacles), per_dev(ev.obs_cov),
                per_dev(ev.counters))

    def run(inputs: SolveInputs, state: PlannerState, params: Params, samples, terms, n_b: int):
        # behaviours split, rest replicated (a SolveInputs of partition specs: a pytree prefix of the inputs)
        in_specs = (SolveInputs._make((rep, rep, rep, P(AXIS))), rep, rep, rep, rep)
        shapes = jax.eval_shape(lambda *a: local(*a), inputs, state.last_offsets, params, samples, terms)
        total_s, costs_s, details_s, own_s, obs_s, cov_s, cnt_s = shapes
        out_specs = (P(AXIS), _split_spec(costs_s, P(AXIS)), _split_spec(details_s, P(AXIS)),
                     Trajectory._make(P(None, AXIS) for _ in Trajectory._fields),     # time-major [T, B]
                     _split_spec(obs_s, P(AXIS)), P(AXIS), _split_spec(cnt_s, P(AXIS)))
        # check_vma=False: the evaluator's scans start from replicated carries that become per-device after one
        # step (behaviour-dependent); the vma checker would demand explicit pcasts inside evaluate_arrays.
        # Nothing here relies on it: replicated outputs are taken explicitly from device 0 below.
        mapped = jax.shard_map(local, mesh=mesh, in_specs=in_specs, out_specs=out_specs, check_vma=False)
        total, costs, details, own, obs, obs_cov, counters = mapped(inputs, state.last_offsets, params, samples,
                                                                    terms)
        cut = lambda a, axis=0: jax.lax.slice_in_dim(a, 0, n_b, axis=axis)
        total = cut(total)
        costs = jax.tree.map(cut, costs)
        details = jax.tree.map(cut, details)
        own = Trajectory(*(cut(a, 1) for a in own))
        obs = jax.tree.map(lambda a: a[0], obs)                                  # device 0's copy
        counters = jax.tree.map(lambda a: jnp.sum(a, dtype=a.dtype), counters)
        best = jnp.argmin(total)
        beh = cut(inputs.behaviours.offsets)
        ev = Evaluation(best, beh[best], total, costs, details, own, obs, obs_cov[0], counters)
        # the same selection rule as solve() (docs/algorithm.md §11), on the unpadded behaviour table
        inp = inputs._replace(behaviours=inputs.behaviours._replace(offsets=beh, mask=cut(inputs.behaviours.mask)))
        plan, nxt = select(ev, state, inp, params, config)
        ev = ev._replace(best=plan.best, best_offsets=plan.offsets)
        return plan, nxt, ev

    jitted = jax.jit(run, static_argnames=("n_b",))
    shardings = (NamedSharding(mesh, P(AXIS)), NamedSharding(mesh, rep))
    return jitted, shardings


def sharded_call(inputs: SolveInputs, state, params: Params, samples, config: PlannerConfig,
                 devices: Sequence | None = None, terms=DEFAULT_TERMS):
    """The pieces of :func:`solve_sharded`: ``(fn, args, n_b)`` with ``fn(*args, n_b=n_b)`` its result.

    ``fn`` is the jitted sharded solve step, ``args`` the validated inputs, padded and placed on the device
    mesh; ahead-of-time use (as the benchmark does): ``fn.lower(*args, n_b=n_b).compile()(*args)``.
    Arguments and errors as :func:`solve_sharded`."""
    if not isinstance(inputs, SolveInputs):
        raise ValueError(f"inputs must be a SolveInputs, got {type(inputs).__name__}")
    if not isinstance(config, PlannerConfig):
        raise ValueError(f"config must be a PlannerConfig, got {type(config).__name__}")
    if not isinstance(state, PlannerState):
        raise ValueError(f"state must be a PlannerState, got {type(state).__name__}")
    terms = check_terms(terms)
    devices = check_devices(devices)
    beh = np.asarray(inputs.behaviours.offsets)
    mask = np.asarray(inputs.behaviours.mask)
    if beh.ndim != 3 or beh.shape[-1] != 2 or mask.shape != beh.shape[:1]:
        raise ValueError(f"behaviours must be [B, n_M, 2] with mask [B], got {beh.shape} and {mask.shape}")
    n_b = beh.shape[0]
    n_real = int(np.count_nonzero(mask))
    if n_b < 1 or n_real < 1:
        raise ValueError(f"need at least one real (unmasked) behaviour, got B={n_b} with {n_real} unmasked")
    fn, (split, rep) = _sharded_fn(config, devices)
    if n_b % len(devices):
        inputs = pad_behaviours(inputs, len(devices))
    inputs = inputs._replace(own=jax.device_put(inputs.own, rep), obstacles=jax.device_put(inputs.obstacles, rep),
                             world=jax.device_put(inputs.world, rep),
                             behaviours=jax.device_put(inputs.behaviours, split))
    state, params, samples, terms = jax.device_put((state, params, samples, terms), rep)
    return fn, (inputs, state, params, samples, terms), n_b


def solve_sharded(inputs: SolveInputs, state, params: Params, samples, config: PlannerConfig,
                  devices: Sequence | None = None, terms=DEFAULT_TERMS):
    """:func:`psbmpc_jax.solve.solve` with the behaviour axis split over ``devices``.

    Args:
        inputs, state, params, samples: as returned by :meth:`psbmpc_jax.Planner.prepare`.
        config: the static :class:`PlannerConfig` (hashable; part of the compile cache key).
        devices: local devices of one platform (default ``jax.local_devices()``).
        terms: the cost terms (default :data:`~psbmpc_jax.evaluate.DEFAULT_TERMS`).

    Returns:
        ``(plan, next_state, evaluation)`` with the same shapes as the single-device solve's (see the module
        docstring for the layout and the one difference, ``n_pc_blocks`` under padding).

    Raises:
        ValueError: empty or mixed-platform (or duplicated) device list, an empty behaviour table, or no
            real (unmasked) behaviour.
    """
    fn, args, n_b = sharded_call(inputs, state, params, samples, config, devices, terms)
    return fn(*args, n_b=n_b)


# ------------------------------------------------------------------------------------------ runs axis
def local_devices(count) -> tuple:
    """The first ``count`` of ``jax.local_devices()`` (``count`` an integer >= 1, or ``"all"``), as a tuple.

    Raises:
        ValueError: ``count`` is neither, or more devices than this process has (the message names how many
            there are, and on the CPU how to split the host into several devices).
    """
    available = tuple(jax.local_devices())
    if isinstance(count, str) and count == "all":
        return available
    if isinstance(count, (bool, np.bool_)) or not isinstance(count, (int, np.integer)) or count < 1:
        raise ValueError(f"devices must be an integer >= 1 or 'all', got {count!r}"[:200])
    if count > len(available):
        kind = available[0].platform
        hint = (" (on the CPU, XLA_FLAGS=--xla_force_host_platform_device_count=N set before JAX starts splits "
                "the host into N devices)" if kind == "cpu" else "")
        raise ValueError(f"devices={int(count)}: this process has {len(available)} local {kind} device"
                         f"{'s' if len(available) != 1 else ''} (jax.local_devices()); allowed: 1..{len(available)} "
                         f"or 'all'{hint}")
    return available[:int(count)]


@lru_cache(maxsize=16)
def _vmapped_solve(config: PlannerConfig, terms: tuple):
    """``vmap`` of the solve step over a batch of solves (chart, grid, behaviours and parameters broadcast): the
    program every device runs on its slice."""
    return jax.vmap(partial(solve_arrays, config=config, terms=terms), in_axes=(SHARED_AXES, 0, None, None))


@lru_cache(maxsize=16)
def _batch_fn(config: PlannerConfig, terms: tuple, devices: tuple):
    """Jitted ``(inputs, states, params, samples, n) -> (plan, states, Evaluation)`` and the (split, replicated)
    shardings (None for one device, where it is the plain jitted vmap)."""
    local = _vmapped_solve(config, terms)
    if len(devices) == 1:
        return jax.jit(local), None
    mesh = Mesh(np.array(devices, dtype=object), (RUNS_AXIS,))
    split, rep = P(RUNS_AXIS), P()
    in_specs = (SolveInputs._make((split, split, rep, rep)), split, rep, rep)    # (own, obstacles, world, behaviours)
    # check_vma=False as in the behaviour split: the evaluator's scans start from replicated carries
    mapped = jax.shard_map(local, mesh=mesh, in_specs=in_specs, out_specs=split, check_vma=False)

    def run(inputs, states, params, samples, n: int):
        return jax.tree.map(lambda a: jax.lax.slice_in_dim(a, 0, n, axis=0),
                            mapped(inputs, states, params, samples))

    return jax.jit(run, static_argnames=("n",)), (NamedSharding(mesh, split), NamedSharding(mesh, rep))


def pad_batch(tree, multiple: int):
    """Every leaf of ``tree`` (leading batch axis n) padded to a multiple of ``multiple`` rows with copies of row
    0 (unchanged when n already is one)."""
    leaves = jax.tree.leaves(tree)
    n = leaves[0].shape[0]
    extra = -n % multiple
    if not extra:
        return tree
    return jax.tree.map(lambda a: jnp.concatenate([a, jnp.repeat(a[:1], extra, axis=0)]), tree)


def solve_batch(inputs: SolveInputs, states: PlannerState, params: Params, samples, config: PlannerConfig,
                terms=DEFAULT_TERMS, devices: Sequence | None = None):
    """A batch of n independent solves (``vmap`` of :func:`psbmpc_jax.solve.solve_arrays`), its batch axis split
    over ``devices`` (module docstring, "Runs axis").

    Args:
        inputs: stacked inputs (:func:`psbmpc_jax.packing.stack`: own-ship and obstacles ``[n, ...]``, the
            world and the behaviour table shared).
        states: the n planner states, leaves ``[n, ...]``.
        params, samples, config, terms: as for :func:`psbmpc_jax.solve.solve` (shared by every solve).
        devices: local devices of one platform (:func:`check_devices`; default: the first local device only,
            the plain single-device call).

    Returns:
        ``(plan, next_states, evaluation)``, leaves ``[n, ...]``, as the single-device vmapped call returns them.
    """
    if not isinstance(inputs, SolveInputs):
        raise ValueError(f"inputs must be a SolveInputs, got {type(inputs).__name__}")
    if not isinstance(config, PlannerConfig):
        raise ValueError(f"config must be a PlannerConfig, got {type(config).__name__}")
    terms = tuple(check_terms(terms))
    devices = check_devices(jax.local_devices()[:1] if devices is None else devices)
    fn, shardings = _batch_fn(config, terms, devices)
    if shardings is None:
        return fn(inputs, states, params, samples)
    n = jax.tree.leaves(inputs.own)[0].shape[0]
    per_solve = pad_batch((inputs.own, inputs.obstacles, states), len(devices))
    split, rep = shardings
    own, obstacles, states = jax.device_put(per_solve, split)
    world, behaviours, params, samples = jax.device_put((inputs.world, inputs.behaviours, params, samples), rep)
    return fn(SolveInputs(own, obstacles, world, behaviours), states, params, samples, n=n)


__all__ = ["solve_sharded", "sharded_call", "check_devices", "solve_batch", "local_devices", "pad_batch"]
