"""Per-platform layout choices: where the CPU's and the GPU's best layouts differ, and how ``"auto"`` picks.

The numbers never depend on the layout (every layout is tested against the float64 reference); only the speed
does.  A CPU runs a few wide threads: sequential loops cost little there and skipping work (culling, compaction)
pays.  A GPU runs thousands of threads in kernels launched one after another: every step of a loop is at least
one launch and a synchronisation, so a loop of a few hundred short steps sets a floor of milliseconds whatever
the work, and doing more arithmetic in fewer, wider kernels pays.  ``psbmpc-jax bench --depth`` counts those
loop steps (:mod:`psbmpc_jax.depth`).

=================  =================================  =============================================
config field       CPU (``auto``)                     GPU and other accelerators (``auto``)
=================  =================================  =============================================
grounding_search   ``bounded``: distance bounds and   ``flat``: every polygon's every edge in one
                   a few exact distances for charts   masked pass (:mod:`psbmpc_jax.edge_blocks`)
                   of a few small polygons
                   (:mod:`psbmpc_jax.bounded_search`),
                   else ``culled``: tiles and edge
                   chunks culled by bounds
pc_layout          ``compact``: only the points that  ``dense`` while every (time, obstacle scenario,
                   pass the sigma shortcut, streamed  behaviour) point fits
                   in a ``while_loop``                :data:`DENSE_PC_ELEMENTS`, else ``compact``
rollout_unroll     1: a ``scan`` of N + 1 steps       :data:`GPU_UNROLL` steps per loop step
rollout_kernel     ``scan``                           ``pallas``: one kernel, each row's rollout in
                                                      registers, where its self-check passes
=================  =================================  =============================================

The platform is ``PlannerConfig.layout_platform``: ``"auto"`` is JAX's default backend (the one a plain ``jit``
runs on); ``"cpu"`` / ``"gpu"`` choose as on that platform whatever runs the program (the benchmark sets it to the
device it times; the depth report uses it to count a GPU program's loops on a CPU).
"""

from __future__ import annotations

#: Values of ``PlannerConfig.grounding_search``.
GROUNDING_SEARCHES = ("auto", "bounded", "culled", "dense", "flat")
#: Values of ``PlannerConfig.pc_layout``.
PC_LAYOUTS = ("auto", "compact", "dense")
#: Values of ``PlannerConfig.rollout_kernel``.
ROLLOUT_KERNELS = ("auto", "scan", "pallas")
#: Values of ``PlannerConfig.layout_platform``.
LAYOUT_PLATFORMS = ("auto", "cpu", "gpu")
#: Rollout steps per loop step on a GPU.  Small on purpose: XLA fuses an unrolled recurrence into ever larger
#: fusions that recompute earlier steps (measured on XLA:CPU, 1014 rows x 300 steps: unroll 1, 2, 4, 8, 16 run
#: 5.1, 13, 48, 200, 293 ms and compile 0.25, 0.31, 0.66, 1.8, 12 s; benchmarks/bench_layout_choices.py,
#: benchmarks/results/layout_choices_cpu_20261128T054017Z.json), so the rollout keeps its loop; a kernel that
#: holds each row's rollout in registers (Pallas, rollout_kernel) is the way to remove it.
GPU_UNROLL = 2
#: Largest number of (time, obstacle scenario, behaviour) points x estimator width (quadrature nodes or samples)
#: that the GPU evaluates densely (2^30: a few GiB of temporaries at most); larger problems stay compact.
DENSE_PC_ELEMENTS = 1 << 30


def _explicit(value, allowed: tuple, what: str):
    """``value`` unless it is ``"auto"`` (then None); a value not in ``allowed`` is refused naming ``what``."""
    if value not in allowed:
        raise ValueError(f"{what} must be one of {allowed}, got {value!r}")
    return None if value == "auto" else value


def platform_of(layout_platform: str = "auto") -> str:
    """``"cpu"`` or ``"gpu"`` (any accelerator) for a ``layout_platform`` value."""
    if _explicit(layout_platform, LAYOUT_PLATFORMS, "PlannerConfig.layout_platform") is not None:
        return layout_platform
    import jax

    return "cpu" if jax.default_backend() == "cpu" else "gpu"


def resolve_search(search: str, platform: str | None = None) -> str:
    """``"auto"`` -> ``"bounded"`` on the CPU (the bounded search where the chart is small enough,
    :func:`psbmpc_jax.bounded_search.use_bounded`, the culled one otherwise), ``"flat"`` on any other platform
    (``platform`` None or ``"auto"``: JAX's default backend); explicit values unchanged.

    Measured (benchmarks/results/README.md): on 2 CPU cores the dense layout is 20-45x slower than the culled
    one; on an H100 it was 1.1-2x faster at 9-2028 behaviours and 2.8x at 21961 vertices.  ``flat`` has no loop
    at all.  On three small islands (176 vertices) the bounded search cut the grounding cost's share of the CPU
    solve 2-2.5x against the culled one (benchmarks/bench_cpu_targets.py)."""
    if _explicit(search, GROUNDING_SEARCHES, "grounding search") is not None:
        return search
    return "bounded" if platform_of(platform or "auto") == "cpu" else "flat"


def resolve_pc_layout(layout: str, points: int, width: int, platform: str | None = None) -> str:
    """The collision kernel's layout for ``points`` (time, obstacle scenario, behaviour) points whose estimator
    evaluates ``width`` nodes or samples each: ``"compact"`` on the CPU; on a GPU ``"dense"`` up to
    :data:`DENSE_PC_ELEMENTS` elements, else ``"compact"``.  Explicit values are kept."""
    if _explicit(layout, PC_LAYOUTS, "PlannerConfig.pc_layout") is not None:
        return layout
    if platform_of(platform or "auto") == "cpu":
        return "compact"
    return "dense" if points * width <= DENSE_PC_ELEMENTS else "compact"


def resolve_rollout_kernel(kernel: str, platform: str | None = None) -> str:
    """The rollouts' implementation: ``"scan"`` on the CPU; on a GPU ``"pallas"`` (one kernel, each row's
    rollout in registers: :mod:`psbmpc_jax.rollout_kernel`) where its compiled self-check passed on this process's
    accelerator, else ``"scan"``.  Choosing the GPU's layouts on a CPU host (``layout_platform="gpu"``) gives
    ``"pallas"`` in Pallas's interpreter.  Explicit values are kept."""
    if _explicit(kernel, ROLLOUT_KERNELS, "PlannerConfig.rollout_kernel") is not None:
        return kernel
    if platform_of(platform or "auto") == "cpu":
        return "scan"
    import jax

    if jax.default_backend() == "cpu":
        return "pallas"
    from .ownship import pallas_available

    return "pallas" if pallas_available() else "scan"


def resolve_unroll(unroll, platform: str | None = None) -> int:
    """Rollout steps per loop step: 1 on the CPU, :data:`GPU_UNROLL` on a GPU; an explicit int is kept."""
    if unroll != "auto":
        return int(unroll)
    return 1 if platform_of(platform or "auto") == "cpu" else GPU_UNROLL


__all__ = [
    "DENSE_PC_ELEMENTS",
    "GPU_UNROLL",
    "GROUNDING_SEARCHES",
    "LAYOUT_PLATFORMS",
    "PC_LAYOUTS",
    "ROLLOUT_KERNELS",
    "platform_of",
    "resolve_pc_layout",
    "resolve_rollout_kernel",
    "resolve_search",
    "resolve_unroll",
]
