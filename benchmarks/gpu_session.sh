#!/usr/bin/env bash
# One prepared GPU measurement session (a lent accelerator for a few minutes): every step is bounded by its own
# timeout and writes into $OUT, so a slow or failing step costs its own slot only.
#
#   OUT=/some/dir bash benchmarks/gpu_session.sh bench     # paper sweep on the GPU, same-host CPU fig5, large
#                                                          # behaviour tables, batched closed loop
#   OUT=/some/dir bash benchmarks/gpu_session.sh tests     # the test suite on the GPU (bounded; verbose log);
#                                                          # TESTS="tests/x.py tests/y.py::z" runs those only,
#                                                          # DIST=load spreads one file's tests over the workers
#   OUT=/some/dir bash benchmarks/gpu_session.sh dense     # exact grounding: culled vs dense search (fig5, fig9),
#                                                          # then fig10/fig6s/fig7s with the dense search
#   OUT=/some/dir bash benchmarks/gpu_session.sh refine    # the PSB-MPC + refinement benchmark (bench_refine.py)
#                                                          # at the slots $SLOTS, bounded by $REFINE_TIMEOUT s
#   OUT=/some/dir bash benchmarks/gpu_session.sh floor     # the latency-floor goals in one device call (<= 430 s):
#                                                          # before/after (.gpu_baseline), profile, fig5 exact/grid,
#                                                          # n_ps 5, 1e5 behaviours, same-host CPU crossover, plan
#                                                          # overhead, depth; then `refine` as a second call
# $OUT comes back as at most 8 files: write into a folder and tar it into $OUT (see docs/performance/gpu.md).
#   SMALL=1 OUT=/tmp/x bash benchmarks/gpu_session.sh bench   # dry run at toy sizes (any machine; also floor)
#
# Wheels of packages missing on the device image (shapely, pyshp) are installed from .whl/ when that folder
# exists (see /work/.library/device/README.md in the project's workplace; elsewhere pip-install the project).
set -u
what=${1:-bench}
: "${OUT:?set OUT to a writable folder}"
export PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false
if [ -d .whl ] && [ -z "${SMALL:-}" ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    && export PYTHONPATH=/tmp/site:$PWD || exit 1
  python3 -m pip install -q --no-index --no-deps --no-build-isolation -e . >/dev/null 2>&1 \
    || echo "editable install failed; using PYTHONPATH"
fi
pj() { python3 -c 'import sys; from psbmpc_jax.apps.cli import main; sys.exit(main(sys.argv[1:]))' "$@"; }
{ nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv 2>&1; nproc;
  python3 -c 'import jax, jaxlib; print(jax.__version__, jaxlib.__version__, jax.devices())' 2>&1; } \
  | tee "$OUT/host.txt"

if [ "$what" = bench ]; then
  if [ -n "${SMALL:-}" ]; then
    R=2; PAPER="--preset smoke"; BIG=39,78; HUGE=117; FIG5="--sweep n_cbs --values 9,39"; RUNS=1,2; DUR=10; DEV=cpu
  else
    R=10; PAPER="--preset paper"; BIG=1014,9984,29952; HUGE=99996; FIG5="--preset fig5"; RUNS=1,16,64; DUR=100; DEV=gpu
  fi
  # 1. the paper sweep (Figs. 5-10 + fig6s/fig7s) on the GPU; the CPU side of the report comes from the
  #    committed 2-core runs and from step 2 (same host)
  timeout -s INT -k 20 210 bash -c "$(declare -f pj); pj bench $PAPER --devices $DEV --reference-budget 0 --repeats $R \
    --warmup 1 --quiet --out $OUT/bench_gpu_paper.jsonl" 2>&1 | tail -3
  # 2. fig5 (n_cbs sweep) on this host's CPU cores: the same-host CPU/GPU crossover
  timeout -s INT -k 10 60 bash -c "$(declare -f pj); pj bench $FIG5 --devices cpu --reference-budget 0 --repeats $R \
    --warmup 1 --quiet --out $OUT/bench_hostcpu_fig5.jsonl" 2>&1 | tail -3
  # 3. the largest behaviour tables (1e3 .. 1e5 behaviours, n_ps 5, two obstacles, 13 polygons)
  #    (1e5 separately: should it fail for memory, the smaller tables are kept)
  for v in $BIG $HUGE; do
    timeout -s INT -k 10 80 bash -c "$(declare -f pj); pj bench --sweep n_cbs --values $v --n-ps 5 --devices $DEV \
      --reference-budget 0 --repeats 5 --warmup 1 --out $OUT/bench_gpu_large_tables.jsonl" 2>&1 | tail -4
  done
  # 4. batched closed loop: loop vs vmap over Monte Carlo runs
  timeout -s INT -k 10 100 python3 benchmarks/bench_sim_batch.py --runs $RUNS --duration $DUR --out "$OUT" 2>&1 | tail -8
  ls -la "$OUT"
elif [ "$what" = floor ]; then
  # the GPU goals of the latency-floor work in one device call: every step bounded by its own limit and by what
  # is left of FLOOR_BUDGET (default 430 s), most important first. Bounds from the H200 run of 2026-11-29
  # (jax 0.11.2): a fig5 solve at 1 014 behaviours compiles in ~33 s on the GPU, at 9 in ~4 s. The refinement
  # (its programs compile for ~150 s) is a second call while the machine is warm, so that both fit 15 minutes of
  # device time: SLOTS=nidelva:1:map,nidelva_u10:1:map REFINE_TIMEOUT=300 bash benchmarks/gpu_session.sh refine
  # Before/after on the same card: put the baseline package in .gpu_baseline/psbmpc_old and carry it (run(carry=[".whl", ".gpu_baseline"])):
  #   git archive <rev> psbmpc_jax | tar -x -C .gpu_baseline && mv .gpu_baseline/psbmpc_jax .gpu_baseline/psbmpc_old
  if [ -n "${SMALL:-}" ]; then
    DEV=cpu; R=2; T="--T 10"; F5="9,39"; BIG=117; N1=39; PROF="--n-cbs 39"
  else
    DEV=gpu; R=10; T=""; F5="9,1014"; BIG=99996; N1=1014; PROF="--n-cbs 1014"
  fi
  end=$(( $(date +%s) + ${FLOOR_BUDGET:-430} ))
  lim() { local left=$(( end - $(date +%s) )); [ "$left" -gt "$1" ] && echo "$1" || echo "$left"; }
  run() { local l; l=$(lim "$1"); shift
    if [ "$l" -lt 15 ]; then echo "skipped (budget spent): $*"; return; fi
    timeout -s INT -k 5 "$l" "$@" 2>&1 | tail -4; }
  b() { local l=$1 name=$2; shift 2
    run "$l" bash -c "$(declare -f pj); pj bench $* --reference-budget 0 --warmup 1 --quiet --out $OUT/$name.jsonl"; }
  # 1. before/after at fig5's 9 and 1 014 behaviours, one interleaved run (when a baseline travelled)
  if [ -d .gpu_baseline/psbmpc_old ]; then
    run 130 python3 benchmarks/bench_ab_points.py --baseline .gpu_baseline --presets fig5 --values "$F5" \
      --repeats "$R" --out "$OUT"
  fi
  # 2. a kernel profile of one 1 014-behaviour solve (kernel groups, times; logs whether the Pallas rollout
  #    kernel passed its check)
  run 75 python3 benchmarks/profile_solve.py $PROF --out "$OUT"
  # 3. fig5 exact (n_ps 1), n_ps 5 with 2 obstacles, grid grounding at 9 / 1 014, then 10^5 behaviours (memory)
  b 70 bench_gpu_fig5 --sweep n_cbs --values $F5 --n-ps 1 --devices $DEV --repeats $R $T
  b 55 bench_gpu_nps5 --sweep n_cbs --values $N1 --n-ps 5 --devices $DEV --repeats $R $T
  b 60 bench_gpu_fig5_grid --sweep n_cbs --values 9,$N1 --n-ps 1 --grounding grid --devices $DEV --repeats $R $T
  b 45 bench_gpu_large --sweep n_cbs --values $BIG --n-ps 5 --devices $DEV --repeats 5 $T
  # 4. the same host's CPU cores (the crossover), Planner.plan host overhead (plan - search)
  b 45 bench_hostcpu_fig5 --sweep n_cbs --values $F5 --n-ps 1 --devices cpu --repeats $R $T
  run 45 python3 benchmarks/bench_solve.py --repeats $R --modes exact --no-grad --out "$OUT"
  # 5. the sequential depth of fig5 with the GPU's layouts (also countable on any CPU)
  b 30 depth_fig5 --preset fig5 --depth --layout-platform gpu $T
  ls -la "$OUT"
elif [ "$what" = paper ]; then
  # the paper sweep alone (with few repeats) and fig5 with grid grounding, then the tests
  timeout -s INT -k 20 250 bash -c "$(declare -f pj); pj bench --preset paper --devices gpu --reference-budget 0 \
    --repeats 5 --warmup 1 --quiet --out $OUT/bench_gpu_paper.jsonl" 2>&1 | tail -3
  timeout -s INT -k 10 45 bash -c "$(declare -f pj); pj bench --preset fig5 --grounding grid --devices gpu \
    --reference-budget 0 --repeats 5 --warmup 1 --quiet --out $OUT/bench_gpu_fig5_grid.jsonl" 2>&1 | tail -3
  OUT=$OUT TEST_TIMEOUT=${TEST_TIMEOUT:-240} bash "$0" tests
elif [ "$what" = dense ]; then
  # the exact grounding searches side by side (culled vs dense, PlannerConfig.grounding_search), then the
  # paper figures the first GPU session did not reach, with the faster search; each step bounded on its own
  if [ -n "${SMALL:-}" ]; then
    R=2; DEV=cpu; F5="--sweep n_cbs --values 9,39 --n-ps 1 --T 10"; F9="--sweep n_cbs --values 9 --T 10"
    F10="--sweep n_so --values 1,2 --T 10"; F6S="--sweep n_ps --values 1,3 --T 10"; F7S="$F6S"
  else
    R=10; DEV=gpu; F5="--preset fig5"; F9="--preset fig9"; F10="--preset fig10"; F6S="--preset fig6s"
    F7S="--preset fig7s"
  fi
  b() { local lim=$1 name=$2; shift 2
    timeout -s INT -k 10 "$lim" bash -c "$(declare -f pj); pj bench $* --devices $DEV --reference-budget 0 \
      --repeats $R --warmup 1 --quiet --out $OUT/$name.jsonl" 2>&1 | tail -2; }
  timeout 60 python3 -m pytest -q -o addopts="" -p no:cacheprovider -n 2 tests/test_sharding.py \
    tests/test_layers.py tests/test_grounding_kernel.py -k "device or private or dense" > "$OUT/tests_gpu_targeted.log" 2>&1
  tail -3 "$OUT/tests_gpu_targeted.log"
  for s in culled dense; do b 75 bench_gpu_fig5 $F5 --grounding-search $s; done
  b 75 bench_gpu_fig10 $F10 --grounding-search culled
  for s in culled dense; do b 40 bench_gpu_fig9 $F9 --grounding-search $s; done
  b 55 bench_gpu_fig6s $F6S --grounding-search culled
  b 70 bench_gpu_fig7s $F7S --grounding-search culled
  ls -la "$OUT"
elif [ "$what" = refine ]; then
  # each refinement slot compiles for a minute or more: a few slots, 10 interleaved rounds; the log keeps the
  # compile lines should the bound stop it before the JSON is written
  timeout -s INT -k 10 "${REFINE_TIMEOUT:-300}" python3 benchmarks/bench_refine.py --repeats "${R:-10}" --warmup 1 \
    --slots "${SLOTS:-nidelva:1:map,nidelva:16:vmap,nidelva_T60:16:vmap}" --out "$OUT" 2>&1 | tee "$OUT/refine.log"
  ls -la "$OUT"
elif [ "$what" = tests ]; then
  # the project's addopts name pytest-rerunfailures, which the device image lacks: replaced here. SIGINT at the
  # bound lets pytest print the failures' tracebacks and the summary (a plain kill loses both)
  timeout -s INT -k 30 "${TEST_TIMEOUT:-300}" python3 -m pytest -v -ra --tb=short -o addopts="" -n "${WORKERS:-12}" \
    --dist "${DIST:-loadfile}" -p no:cacheprovider --timeout 240 -W ignore ${TESTS:-} > "$OUT/tests_gpu.log" 2>&1
  echo "pytest exit: $?" | tee -a "$OUT/tests_gpu.log"
  grep -cE " PASSED" "$OUT/tests_gpu.log"; grep -E " FAILED| ERROR" "$OUT/tests_gpu.log" | head -40
  tail -5 "$OUT/tests_gpu.log"
fi
