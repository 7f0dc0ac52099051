#!/usr/bin/env bash
# The device check of the "cuda" backend, as one run on a GPU machine (results under $OUT):
# build the kernels in place, the benchmark, the GPU tests, compute-sanitizer on a small stack.
#     OUT=/tmp/gpu bash benchmarks/gpu_device_run.sh
set -u
OUT=${OUT:-/tmp/lcpcli-gpu}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD"
PY=${PYTHON:-python3}
{ nvidia-smi -L; $PY --version; $PY -c "import cupy, numpy; print('cupy', cupy.__version__, 'numpy', numpy.__version__)"; } 2>&1 | tee "$OUT/env.txt"
t0=$(date +%s)
if ! timeout 120 $PY setup.py build_ext --inplace -j "$(nproc)" > "$OUT/build.log" 2>&1; then
    echo "build failed (see build.log)"; tail -5 "$OUT/build.log"
    if [ -d .dev312 ]; then echo "using the carried prebuilt modules"; cp -r .dev312/lcpcli/. lcpcli/; fi
fi
echo "build: $(( $(date +%s) - t0 )) s"
timeout 200 $PY benchmarks/bench_gpu.py --out "$OUT/bench_gpu.json" 2>&1 | tee "$OUT/bench.txt" | tail -8
echo "bench: $(( $(date +%s) - t0 )) s"
timeout 150 $PY -m pytest tests/solvers/test_gpu_backend.py tests/solvers/test_single_source.py \
    -p no:cacheprovider -o addopts="" -q -rs --timeout 120 2>&1 | tee "$OUT/tests.txt" | tail -25
echo "tests: $(( $(date +%s) - t0 )) s"
if command -v compute-sanitizer > /dev/null; then
    timeout 60 compute-sanitizer --tool memcheck --print-limit 20 $PY benchmarks/gpu_sanitize.py > "$OUT/memcheck.txt" 2>&1
    tail -4 "$OUT/memcheck.txt"
    timeout 60 compute-sanitizer --tool racecheck --print-limit 20 $PY benchmarks/gpu_sanitize.py warp > "$OUT/racecheck.txt" 2>&1
    tail -3 "$OUT/racecheck.txt"
fi
echo "all: $(( $(date +%s) - t0 )) s"
