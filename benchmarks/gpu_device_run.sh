#!/usr/bin/env bash
# The device check of the "cuda" backend, as one run on a GPU machine (results under $OUT):
# build the package in place (and, beside it, the warp kernel with nvcc for each register
# budget, for the sweep), the sweep of the warp kernel's speed choices (benchmarks/gpu_sweep.py,
# against an earlier lcp_stack.h when BASELINE names one), the benchmark with the sweep's best
# table, the GPU tests, compute-sanitizer on a small stack.
#     OUT=/tmp/gpu [BASELINE=old/lcp_stack.h] bash benchmarks/gpu_device_run.sh
set -u
OUT=${OUT:-/tmp/lcpcli-gpu}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD"
PY=${PYTHON:-python3}
{ nvidia-smi -L; $PY --version; $PY -c "import cupy, numpy; print('cupy', cupy.__version__, 'numpy', numpy.__version__)"; nvcc --version | tail -1; } 2>&1 | tee "$OUT/env.txt"
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
if ! timeout 120 $PY setup.py build_ext --inplace -j "$(nproc)" > "$OUT/build.log" 2>&1; then
    echo "build failed (see build.log)"; tail -5 "$OUT/build.log"
fi
wait
ls "$CUB"/*/ 2>&1 | tr '\n' ' '; echo
echo "build: $(( $(date +%s) - t0 )) s"
OLD=(); [ -d "$CUB/old" ] && OLD=(--old-cubins "$CUB/old")
timeout 150 $PY benchmarks/gpu_sweep.py --cubins "$CUB/new" "${OLD[@]}" --out "$OUT/gpu_sweep.json" \
    --table-out "$OUT/warp_table.json" 2>&1 | tee "$OUT/sweep.txt" | grep -v '"min_blocks": [0-9], "lanes"' | tail -12
echo "sweep: $(( $(date +%s) - t0 )) s"
TABLE=(); [ -s "$OUT/warp_table.json" ] && TABLE=(--table "$OUT/warp_table.json")
timeout 120 $PY benchmarks/bench_gpu.py "${TABLE[@]}" --min-blocks "" --out "$OUT/bench_gpu.json" 2>&1 \
    | tee "$OUT/bench.txt" | tail -4 | cut -c1-1500
echo "bench: $(( $(date +%s) - t0 )) s"
timeout 120 $PY -m pytest tests/solvers/test_gpu_backend.py -p no:cacheprovider -o addopts="" -q -rs \
    -x --timeout 110 2>&1 | tee "$OUT/tests.txt" | tail -6
echo "tests: $(( $(date +%s) - t0 )) s"
if command -v compute-sanitizer > /dev/null; then
    timeout 45 compute-sanitizer --tool racecheck --print-limit 20 $PY benchmarks/gpu_sanitize.py warp warp8 > "$OUT/racecheck.txt" 2>&1
    tail -3 "$OUT/racecheck.txt"
    timeout 45 compute-sanitizer --tool memcheck --print-limit 20 $PY benchmarks/gpu_sanitize.py warp warp8 > "$OUT/memcheck.txt" 2>&1
    tail -3 "$OUT/memcheck.txt"
fi
echo "all: $(( $(date +%s) - t0 )) s"
