#!/usr/bin/env bash
# The device check of the "cuda" backend, as one run on a GPU machine (results under $OUT):
# build the package in place (and, beside it, the warp kernel with nvcc for each register
# budget, for the sweep), the sweep of the warp kernel's speed choices (benchmarks/gpu_sweep.py,
# against an earlier lcp_stack.h when BASELINE names one), the benchmark with the sweep's best
# table, the GPU tests, compute-sanitizer (racecheck, memcheck) on small stacks.
#     OUT=/tmp/gpu [BASELINE=old/lcp_stack.h] bash benchmarks/gpu_device_run.sh
set -u
OUT=${OUT:-/tmp/lcpcli-gpu}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD"
PY=${PYTHON:-python3}
LOG="$OUT/env.txt"
{ nvidia-smi -L; $PY --version; $PY -c "import cupy, numpy; print('cupy', cupy.__version__, 'numpy', numpy.__version__)"; nvcc --version | tail -1; } 2>&1 | tee "$LOG"
t0=$(date +%s)
CUB=$(mktemp -d)
SM=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader | head -1 | tr -d '.')
build_cubins() {  # $1: header, $2: folder; one nvcc per register budget, in parallel
    mkdir -p "$2"
    for mb in 1 2 3 4; do
        nvcc -cubin -arch="sm_$SM" --fmad=false -std=c++11 -DLCP_WARP_MIN_BLOCKS=$mb -x cu \
            -o "$2/mb$mb.cubin" "$1" > "$2/mb$mb.log" 2>&1 &
    done
}
if command -v nvcc > /dev/null; then
    build_cubins lcpcli/solvers/kernels/src/lcp_stack.h "$CUB/new"
    [ -n "${BASELINE:-}" ] && build_cubins "$BASELINE" "$CUB/old"
fi
if ! timeout 120 $PY setup.py build_ext --inplace -j "$(nproc)" > "$CUB/build.log" 2>&1; then
    echo "build failed"; tail -5 "$CUB/build.log" | tee -a "$LOG"
fi
wait
echo "build: $(( $(date +%s) - t0 )) s, cubins: $(ls "$CUB"/*/*.cubin 2>/dev/null | wc -l)" | tee -a "$LOG"
OLD=(); [ -d "$CUB/old" ] && OLD=(--old-cubins "$CUB/old")
timeout 150 $PY benchmarks/gpu_sweep.py --cubins "$CUB/new" "${OLD[@]}" --out "$OUT/gpu_sweep.json" \
    --table-out "$OUT/warp_table.json" 2>&1 | grep -v '"min_blocks": [0-9], "lanes"' | tail -12
echo "sweep: $(( $(date +%s) - t0 )) s"
TABLE=(); [ -s "$OUT/warp_table.json" ] && TABLE=(--table "$OUT/warp_table.json")
timeout 120 $PY benchmarks/bench_gpu.py "${TABLE[@]}" --min-blocks "" --out "$OUT/bench_gpu.json" 2>&1 \
    | tee "$OUT/bench.txt" | tail -4 | cut -c1-600
echo "bench: $(( $(date +%s) - t0 )) s"
timeout 160 $PY -m pytest tests/solvers/test_gpu_backend.py -p no:cacheprovider -o addopts="" -q -rs \
    --timeout 150 2>&1 | tee "$OUT/tests.txt" | tail -4
echo "tests: $(( $(date +%s) - t0 )) s"
if command -v compute-sanitizer > /dev/null; then
    timeout 70 compute-sanitizer --tool racecheck --print-limit 20 $PY benchmarks/gpu_sanitize.py warp warp8 > "$OUT/sanitize.txt" 2>&1
    timeout 50 compute-sanitizer --tool memcheck --print-limit 20 $PY benchmarks/gpu_sanitize.py warp warp8 >> "$OUT/sanitize.txt" 2>&1
    grep -ci "hazard\|error" "$OUT/sanitize.txt"; grep -i "summary" "$OUT/sanitize.txt"; tail -2 "$OUT/sanitize.txt"
fi
echo "all: $(( $(date +%s) - t0 )) s"
