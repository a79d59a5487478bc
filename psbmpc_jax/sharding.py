"""Multi-device evaluation: the behaviour axis split over several local devices with ``jax.shard_map``.

This mirrors splitting the CUDA grid of the original PSB-MPC over several GPUs: every control behaviour
is independent of the others (kernel 1 rolls out one own-ship trajectory per behaviour, kernel 2 scores it
against every obstacle scenario and polygon), so the B behaviours are cut into equal contiguous slices,
one per device, and each device runs the ordinary single-device evaluator
(:func:`psbmpc_jax.evaluate.evaluate_arrays`) on its slice.

Layout (a 1-D :class:`jax.sharding.Mesh` with one axis named ``"b"``, D devices):

* ``behaviours [B, n_M, 2]`` and ``beh_mask [B]`` are split along B (``PartitionSpec("b")``).  When B is
  not a multiple of D, B is padded on the host up to ``Bp = ceil(B / D) * D`` with masked copies of
  behaviour 0 (masked behaviours get cost +inf inside the evaluator); the padding is cut off again, so the
  result has exactly the shapes :func:`~psbmpc_jax.evaluate.evaluate` returns.
* Everything else (own-ship, obstacles, polygons, distance grid, parameters, random-number table) is
  replicated.  In particular the obstacle prediction (scenario rollouts and covariances) is recomputed on
  every device: it is O(O·S·T) work, tiny next to the O(B·O·S·T) collision kernel, and replicating it
  avoids any cross-device communication inside the evaluator.
* Per-behaviour outputs (``total, do, colregs, so, path [B]``, ``C, mu [B, O, S]``, ``so_j [B, P]`` and the
  own-ship trajectories, which are time-major ``[T, B]`` so B is their axis 1) are concatenated along B;
  the replicated outputs (``obstacles``, ``obs_cov``) come from one device; ``n_pc_blocks`` is summed over
  the devices; ``best`` is the global argmin over the concatenated totals (first index on ties, as
  ``jnp.argmin``) and ``best_offsets = behaviours[best]``.

The whole thing (shard_map + the final reduction) is jitted once per (config, device set) and, through
``jax.jit``'s own cache, once per input shapes/dtypes; values never recompile.

Results equal the single-device :func:`~psbmpc_jax.evaluate.evaluate` per behaviour (every behaviour's
costs are computed by the same code from the same inputs; in float64 they agree to the last bits or
within rounding).  One difference: ``n_pc_blocks`` counts the work actually done, so when B had to be
padded to a multiple of D the extra masked copies of behaviour 0 add their collision-probability blocks
(exactly the single-device count when D divides B).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from .evaluate import Evaluation, SituationArrays, evaluate_arrays
from .ownship import Trajectory
from .params import Params, PlannerConfig

AXIS = "b"


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


@lru_cache(maxsize=32)
def _sharded_fn(config: PlannerConfig, devices: tuple):
    """Jitted ``(arrays, params, samples, n_b) -> Evaluation`` for one config and device set.

    ``arrays`` already holds the padded behaviour axis ``Bp`` (a multiple of ``len(devices)``); the
    output is cut back to the first ``n_b`` behaviours (``n_b`` static)."""
    mesh = Mesh(np.array(devices, dtype=object), (AXIS,))
    rep = P()
    in_arr_spec = SituationArrays(**{f: rep for f in SituationArrays._fields})._replace(
        behaviours=P(AXIS), beh_mask=P(AXIS))
    traj_b = Trajectory(*(P(None, AXIS) for _ in Trajectory._fields))       # time-major [T, B]

    def local(sit: SituationArrays, params: Params, samples):
        ev = evaluate_arrays(sit, params, samples, config)
        # replicated outputs and the block count get a leading per-device axis: [D, ...] after the map
        per_dev = lambda a: a[None]
        return (ev.total, ev.do, ev.colregs, ev.so, ev.path, ev.C, ev.mu, ev.so_j, ev.own,
                jax.tree_util.tree_map(per_dev, ev.obstacles), per_dev(ev.obs_cov), per_dev(ev.n_pc_blocks))

    out_specs = (P(AXIS),) * 8 + (traj_b, P(AXIS), P(AXIS), P(AXIS))
    # check_vma=False: the evaluator's scans start from replicated carries that become per-device after one
    # step (behaviour-dependent); the vma checker would demand explicit pcasts inside evaluate_arrays.
    # Nothing here relies on it: replicated outputs are taken explicitly from device 0 below.
    mapped = jax.shard_map(local, mesh=mesh, in_specs=(in_arr_spec, rep, rep), out_specs=out_specs,
                           check_vma=False)

    def run(sit: SituationArrays, params: Params, samples, n_b: int) -> Evaluation:
        (total, do, colregs, so, path, c, mu, so_j, own, obs, obs_cov, n_blk) = mapped(sit, params, samples)
        cut = lambda a, axis=0: jax.lax.slice_in_dim(a, 0, n_b, axis=axis)
        total, do, colregs, so, path = (cut(a) for a in (total, do, colregs, so, path))
        c, mu, so_j = cut(c), cut(mu), cut(so_j)
        own = Trajectory(*(cut(a, 1) for a in own))
        obs = jax.tree_util.tree_map(lambda a: a[0], obs)                        # device 0's copy
        obs_cov = obs_cov[0]
        best = jnp.argmin(total)
        beh = cut(sit.behaviours)
        return Evaluation(best, beh[best], total, do, colregs, so, path, c, mu, so_j, own, obs, obs_cov,
                          jnp.sum(n_blk, dtype=n_blk.dtype))

    jitted = jax.jit(run, static_argnames=("n_b",))
    shardings = (
        SituationArrays(**{f: NamedSharding(mesh, spec) for f, spec in in_arr_spec._asdict().items()}),
        NamedSharding(mesh, rep),
    )
    return jitted, shardings


def pad_behaviours(behaviours, beh_mask, n_devices: int):
    """Host padding of the behaviour axis to a multiple of ``n_devices`` with masked copies of behaviour 0.

    Returns NumPy ``(behaviours [Bp, n_M, 2], beh_mask [Bp])`` (unchanged values when nothing is needed)."""
    beh = np.asarray(behaviours)
    mask = np.asarray(beh_mask)
    n_b = beh.shape[0]
    n_pad = -n_b % n_devices
    if n_pad:
        beh = np.concatenate([beh, np.repeat(beh[:1], n_pad, axis=0)])
        mask = np.concatenate([mask, np.zeros(n_pad, dtype=mask.dtype)])
    return beh, mask


def sharded_call(arrays: SituationArrays, params: Params, samples, config: PlannerConfig,
                 devices: Sequence | None = None):
    """The pieces of :func:`evaluate_sharded`: ``(fn, args, n_b)`` with ``fn(*args, n_b=n_b)`` its result.

    ``fn`` is the jitted sharded evaluator, ``args`` the validated inputs, padded and placed on the device
    mesh; ahead-of-time use (as the benchmark does): ``fn.lower(*args, n_b=n_b).compile()(*args)``.
    Arguments and errors as :func:`evaluate_sharded`."""
    if not isinstance(arrays, SituationArrays):
        raise ValueError(f"arrays must be a SituationArrays, got {type(arrays).__name__}")
    if not isinstance(config, PlannerConfig):
        raise ValueError(f"config must be a PlannerConfig, got {type(config).__name__}")
    devices = check_devices(devices)
    beh = np.asarray(arrays.behaviours)
    mask = np.asarray(arrays.beh_mask)
    if beh.ndim != 3 or beh.shape[-1] != 2 or mask.shape != beh.shape[:1]:
        raise ValueError(f"behaviours must be [B, n_M, 2] with beh_mask [B], got {beh.shape} and {mask.shape}")
    n_b = beh.shape[0]
    n_real = int(np.count_nonzero(mask))
    if n_b < 1 or n_real < 1:
        raise ValueError(f"need at least one real (unmasked) behaviour, got B={n_b} with {n_real} unmasked")
    fn, (sit_shardings, rep_sharding) = _sharded_fn(config, devices)
    if n_b % len(devices):
        beh, mask = pad_behaviours(beh, mask, len(devices))
        arrays = arrays._replace(behaviours=jnp.asarray(beh, arrays.behaviours.dtype),
                                 beh_mask=jnp.asarray(mask, arrays.beh_mask.dtype))
    arrays = jax.device_put(arrays, sit_shardings)
    params = jax.device_put(params, rep_sharding)
    if samples is not None:
        samples = jax.device_put(samples, rep_sharding)
    return fn, (arrays, params, samples), n_b


def evaluate_sharded(arrays: SituationArrays, params: Params, samples, config: PlannerConfig,
                     devices: Sequence | None = None) -> Evaluation:
    """:func:`psbmpc_jax.evaluate.evaluate` with the behaviour axis split over ``devices``.

    Args:
        arrays, params, samples: as returned by :meth:`psbmpc_jax.Planner.prepare`.
        config: the static :class:`PlannerConfig` (hashable; part of the compile cache key).
        devices: local devices of one platform (default ``jax.local_devices()``).

    Returns:
        An :class:`Evaluation` with the same shapes as the single-device evaluator's (see the module
        docstring for the layout and the one difference, ``n_pc_blocks`` under padding).

    Raises:
        ValueError: empty or mixed-platform (or duplicated) device list, an empty behaviour table, or no
            real (unmasked) behaviour.
    """
    fn, args, n_b = sharded_call(arrays, params, samples, config, devices)
    return fn(*args, n_b=n_b)


__all__ = ["evaluate_sharded", "sharded_call", "check_devices", "pad_behaviours"]
