#!/usr/bin/env bash
# The device check of the "cuda" backend, as one run on a GPU machine (results under $OUT):
# build the package in place and, beside it, the warp kernel with nvcc for each register
# budget (and each LCP_PIVOT_ROWS in ROWS); the sweep of the warp kernel's speed choices
# (benchmarks/gpu_sweep.py; then the other ROWS and an earlier lcp_stack.h of the same kernel
# signature, BASELINE, at n = 12 and 50 in the same run); the benchmark with the sweep's best
# table; then, as asked: PROFILE=1 Nsight Compute on one launch
# per size (benchmarks/gpu_profile.py), TESTS=1 the GPU tests, SANITIZE=1 compute-sanitizer.
#     OUT=/tmp/gpu [BASELINE=old/lcp_stack.h] [ROWS="8 4"] [BLOCKS=1,2] [WARPS=8,1] [PROFILE=1] \
#         [TESTS=1] [SANITIZE=1] [VARIANTS="copy8:-DLCP_COPY_BATCH=8 rows4:-DLCP_PIVOT_ROWS=4"] \
#         bash benchmarks/gpu_device_run.sh
# VARIANTS: NAME:OPTIONS pairs (options comma-separated -D macros of lcp_stack.h's speed
# choices), each built beside the others and swept at n = 12 and 50 in the same run, its
# outputs checked bit for bit against the first ROWS build's (same_as_against).  Cubins are
# built for the register budgets in BLOCKS only (ptxas -v logs: $OUT/run.tar.gz's ptxas_*).
# Everything but the last lines printed goes to $OUT/run.tar.gz.
set -u
OUT=${OUT:-/tmp/lcpcli-gpu}
R="$OUT/r"
mkdir -p "$R"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD"
PY=${PYTHON:-python3}
ROWS=${ROWS:-8}
{ nvidia-smi -L; $PY --version; $PY -c "import cupy, numpy; print('cupy', cupy.__version__, 'numpy', numpy.__version__)"; nvcc --version | tail -1; } 2>&1 | tee "$R/env.txt"
t0=$(date +%s)
CUB=$(mktemp -d)
SM=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader | head -1 | tr -d '.')
build_cubins() {  # $1: header, $2: folder, $3...: extra nvcc options; one nvcc per budget
    local h=$1 d=$2; shift 2
    mkdir -p "$d"
    for mb in $(echo "${BLOCKS:-1,2,3,4}" | tr ',' ' '); do
        nvcc -cubin -arch="sm_$SM" --fmad=false -std=c++11 -Xptxas -v -DLCP_WARP_MIN_BLOCKS=$mb "$@" -x cu \
            -o "$d/mb$mb.cubin" "$h" > "$d/mb$mb.log" 2>&1 &
    done
}
for rows in $ROWS; do build_cubins lcpcli/solvers/kernels/src/lcp_stack.h "$CUB/rows$rows" -DLCP_PIVOT_ROWS=$rows; done
[ -n "${BASELINE:-}" ] && build_cubins "$BASELINE" "$CUB/base"
for v in ${VARIANTS:-}; do
    build_cubins lcpcli/solvers/kernels/src/lcp_stack.h "$CUB/v_${v%%:*}" $(echo "${v#*:}" | tr ',' ' ')
done
[ "${PROFILE:-0}" = 1 ] && build_cubins lcpcli/solvers/kernels/src/lcp_stack.h "$CUB/prof" -lineinfo
if ! timeout 150 $PY setup.py build_ext --inplace -j "$(nproc)" > "$R/build.log" 2>&1; then
    echo "build failed"; tail -5 "$R/build.log"
fi
wait
echo "build: $(( $(date +%s) - t0 )) s, cubins: $(ls "$CUB"/*/*.cubin 2>/dev/null | wc -l)"
# NVRTC builds of the package (CuPy's disk cache) for the tests, in the background
( timeout 200 $PY -c "
import concurrent.futures as cf
from lcpcli.solvers.backends import cuda
def build(extra):
    cuda._module(0, extra).get_function('lcp_lemke_warp_stack')
    return extra
opts = [()] + [('-DLCP_WARP_MIN_BLOCKS=%d' % k,) for k in (2, 3, 4)]
with cf.ProcessPoolExecutor(4) as ex:
    print('nvrtc cache:', list(ex.map(build, opts)))
" > "$R/nvrtc.txt" 2>&1 & )
SETS=""; for rows in $ROWS; do SETS="$SETS rows$rows"; done
[ -d "$CUB/base" ] && SETS="$SETS base"
for v in ${VARIANTS:-}; do SETS="$SETS v_${v%%:*}"; done
first=1
FIRSTSET=""
for set in $SETS; do
    if [ $first = 1 ]; then
        FIRSTSET=$set
        timeout 200 $PY benchmarks/gpu_sweep.py --cubins "$CUB/$set" --blocks "${BLOCKS:-1,2,3,4}" \
            ${WARPS:+--warps "$WARPS"} \
            --out "$R/gpu_sweep_$set.json" --table-out "$R/warp_table.json" 2>&1 \
            | grep -v '"min_blocks": [0-9], "lanes"' | tail -6 | cut -c1-400
    else
        timeout 100 $PY benchmarks/gpu_sweep.py --cubins "$CUB/$set" --sizes 12,50 --blocks "${BLOCKS:-1,2,3,4}" \
            --against "$R/gpu_sweep_$FIRSTSET.json" \
            --out "$R/gpu_sweep_$set.json" 2>&1 | grep '"best"' | cut -c1-400
    fi
    first=0
    echo "sweep $set: $(( $(date +%s) - t0 )) s"
done
TABLE=(); [ -s "$R/warp_table.json" ] && TABLE=(--table "$R/warp_table.json")
FIRST=$(echo $ROWS | cut -d' ' -f1)
if [ "${PROFILE:-0}" = 1 ] && command -v ncu > /dev/null; then
    cp "$R/warp_table.json" "$CUB/prof/" 2>/dev/null
    timeout 150 ncu --clock-control none --kernel-name lcp_lemke_warp_stack --launch-count 2 \
        --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats \
        --section SchedulerStats --section SourceCounters --section MemoryWorkloadAnalysis \
        --import-source yes -f -o "$R/prof" $PY benchmarks/gpu_profile.py --cubins "$CUB/prof" \
        > "$R/ncu_run.txt" 2>&1
    tail -3 "$R/ncu_run.txt"
    ncu --import "$R/prof.ncu-rep" --page details > "$R/prof_details.txt" 2>&1
    ncu --import "$R/prof.ncu-rep" --page source --csv --print-source cuda > "$R/prof_source.csv" 2>&1 \
        || echo "no source page"
    ncu --import "$R/prof.ncu-rep" --page source --csv --print-source sass > "$R/prof_sass.csv" 2>&1 \
        || echo "no sass page"
    grep -i "stall\|issued\|occupancy\|warp cycles per\|registers\|duration" "$R/prof_details.txt" | head -60 | cut -c1-150
    echo "profile: $(( $(date +%s) - t0 )) s"
fi
timeout 200 $PY benchmarks/bench_gpu.py --cubins "$CUB/rows$FIRST" "${TABLE[@]}" --min-blocks "" \
    --profile --out "$R/bench_gpu.json" 2>&1 | tee "$R/bench.txt" | grep 'end_to_end"\|h2d' | cut -c1-200
echo "bench: $(( $(date +%s) - t0 )) s"
# the GPU tests and the race checker side by side (neither is timed)
if [ "${SANITIZE:-0}" = 1 ] && command -v compute-sanitizer > /dev/null; then
    ( timeout 100 compute-sanitizer --tool racecheck --print-limit 20 $PY benchmarks/gpu_sanitize.py warp warp8 \
        > "$R/sanitize.txt" 2>&1 ) &
fi
if [ "${TESTS:-0}" = 1 ]; then
    timeout 240 $PY -m pytest tests/solvers/test_gpu_backend.py -p no:cacheprovider -o addopts="" -q -rs \
        --timeout 200 -x 2>&1 | tee "$R/tests.txt" | tail -4
    echo "tests: $(( $(date +%s) - t0 )) s"
fi
wait
if [ -s "$R/sanitize.txt" ]; then
    grep -ci "hazard\|error" "$R/sanitize.txt"; grep -i "summary\|same" "$R/sanitize.txt" | head -12
fi
for f in "$CUB"/*/mb*.log; do  # ptxas -v: registers and spills of every build
    [ -f "$f" ] && cp "$f" "$R/ptxas_$(basename "$(dirname "$f")")_$(basename "$f")"
done
tar czf "$OUT/run.tar.gz" -C "$OUT" r && rm -rf "$R"
echo "all: $(( $(date +%s) - t0 )) s"
