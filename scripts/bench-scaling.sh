#!/usr/bin/env bash
# Scaling of global registration with the dense graph's size (bench/scaling_bench.cpp):
# builds scaling_bench (Release), runs it on synthetic drives of 100, 300, 1000, 3000 frames,
# writes bench/results/scaling-<git short sha>.json, then prints a table, the log-log slopes of
# time vs factors, and where GRE full stops fitting in 24 GiB.
#
#   scripts/bench-scaling.sh [--max-frames N] [--voxel M] [--no-build] [extra Google Benchmark flags]
#
# Environment: CARAT_SCALING_MAX_FRAMES (same as --max-frames; e.g. 1000 for a quick run),
# CARAT_SCALING_VOXEL_M (same as --voxel: the scans' voxel, default 0.5 m; a run with another
# voxel writes scaling-<sha>-voxel<M>.json),
# CARAT_SCALING_ITERATIONS (LM iterations per solve, default 3), CARAT_SCALING_THREADS,
# CARAT_SCALING_FULL_LIMIT_GIB (full is skipped above this, default 8), CARAT_BUILD_DIR
# (default build), CARAT_SCALING_BUDGET_GIB (the extrapolation's memory, default 24).
# Only needs python3's standard library for the analysis.
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir="${CARAT_BUILD_DIR:-build}"
do_build=1
bench_args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --max-frames) export CARAT_SCALING_MAX_FRAMES="$2"; shift 2 ;;
    --max-frames=*) export CARAT_SCALING_MAX_FRAMES="${1#*=}"; shift ;;
    --voxel) export CARAT_SCALING_VOXEL_M="$2"; shift 2 ;;
    --voxel=*) export CARAT_SCALING_VOXEL_M="${1#*=}"; shift ;;
    --no-build) do_build=0; shift ;;
    *) bench_args+=("$1"); shift ;;
  esac
done

if [[ $do_build == 1 ]]; then
  cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release ${CARAT_CMAKE_ARGS:-}
  cmake --build "$build_dir" --target scaling_bench -j"$(nproc)"
fi

sha="$(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
mkdir -p bench/results
suffix=""
if [[ -n "${CARAT_SCALING_VOXEL_M:-}" ]]; then suffix="-voxel${CARAT_SCALING_VOXEL_M}"; fi
out="bench/results/scaling-$sha$suffix.json"
echo "== scaling_bench (max frames ${CARAT_SCALING_MAX_FRAMES:-3000}, voxel ${CARAT_SCALING_VOXEL_M:-0.5} m) -> $out" >&2
"./$build_dir/bench/scaling_bench" --benchmark_format=json --benchmark_out="$out" \
  ${bench_args[@]+"${bench_args[@]}"} > /dev/null

python3 - "$out" "${CARAT_SCALING_BUDGET_GIB:-24}" <<'PY'
import json, math, sys

path, budget_gib = sys.argv[1], float(sys.argv[2])
GiB, MiB = 1024.0 ** 3, 1024.0 ** 2
SCALE = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}

runs = {}  # (kind, frames) -> benchmark entry
for b in json.load(open(path))["benchmarks"]:
    if b.get("run_type", "iteration") != "iteration":
        continue
    kind = b["name"].split("/")[0].replace("BM_", "")
    frames = int(b["name"].split("/")[1])
    runs[(kind, frames)] = b

def seconds(b):
    return b["real_time"] * SCALE[b.get("time_unit", "ns")]

def ok(b):
    return b is not None and not b.get("error_occurred", False)

def fit(points):
    """Least-squares slope and intercept of log(y) vs log(x)."""
    pts = [(math.log(x), math.log(y)) for x, y in points if x > 0 and y > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    if sxx == 0:
        return None
    slope = sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx
    return slope, my - slope * mx

sizes = sorted({f for _, f in runs})
header = ("frames", "factors", "build+compr s", "iter exact s", "iter full s",
          "exact MiB", "full MiB", "RSS exact GiB", "RSS full GiB")
print("\n%7s %9s %14s %13s %12s %10s %10s %14s %13s" % header)
build_pts, exact_pts, full_pts, bytes_pts, exact_bytes_pts, factor_pts = [], [], [], [], [], []
for f in sizes:
    be, ie, fu = (runs.get((k, f)) for k in ("BuildExact", "IterationExact", "IterationFull"))
    c = (be or ie or fu)
    if c is None:  # only the whole-optimization benchmarks ran at this size
        continue
    factors = c.get("factors", 0)
    factor_pts.append((f, factors))
    row = ["%7d" % f, "%9d" % factors]
    if ok(be):
        build_pts.append((factors, seconds(be)))
        row.append("%14.2f" % seconds(be))
    else:
        row.append("%14s" % "-")
    if ok(ie):
        exact_pts.append((factors, ie["per_iteration_s"]))
        row.append("%13.3f" % ie["per_iteration_s"])
    else:
        row.append("%13s" % "-")
    if ok(fu):
        full_pts.append((factors, fu["per_iteration_s"]))
        row.append("%12.3f" % fu["per_iteration_s"])
    else:
        row.append("%12s" % "skipped")
    src = be if ok(be) else ie
    if ok(src):
        cc = src
        exact_bytes_pts.append((factors, cc["residual_bytes"]))
        bytes_pts.append((factors, cc["correspondence_bytes"]))
        row.append("%10.1f" % (cc["residual_bytes"] / MiB))
        full_mib = cc["correspondence_bytes"] / MiB
        row.append("%10.1f" % full_mib if ok(fu) else "%9.0f*" % full_mib)
    else:
        row += ["%10s" % "-", "%10s" % "-"]
    rss_e = max([r.get("peak_rss_bytes", 0) for r in (be, ie) if ok(r)] or [0])
    row.append("%14.2f" % (rss_e / GiB))
    row.append("%13.2f" % (fu["peak_rss_bytes"] / GiB) if ok(fu) else "%13s" % "-")
    print(" ".join(row))
print("(* full not run: the bytes its correspondences would take, measured by the exact build)")

print("\nlog-log least-squares slopes (time ~ factors^slope; last: factors ~ frames^slope):")
for label, pts in (("build + compress (exact)", build_pts),
                   ("LM iteration, exact", exact_pts),
                   ("LM iteration, full", full_pts),
                   ("factors vs frames", factor_pts)):
    r = fit(pts)
    print("  %-26s %s" % (label, "%.2f  (%d sizes)" % (r[0], len(pts)) if r else "n/a (fewer than 2 sizes)"))

if bytes_pts:
    # Bytes per factor, least squares through the origin (memory is linear in factors).
    per_factor = sum(x * y for x, y in bytes_pts) / sum(x * x for x, _ in bytes_pts)
    exact_per_factor = sum(x * y for x, y in exact_bytes_pts) / sum(x * x for x, _ in exact_bytes_pts)
    limit_factors = budget_gib * GiB / per_factor
    ff = fit(factor_pts)
    frames_txt = ""
    if ff:
        frames_txt = ", about %.0f frames of this drive" % math.exp((math.log(limit_factors) - ff[1]) / ff[0])
    print("\nmemory: full %.1f KiB/factor, exact %.2f KiB/factor (%.0fx less)"
          % (per_factor / 1024, exact_per_factor / 1024, per_factor / exact_per_factor))
    print("full stops fitting in %.0f GiB at about %.0f factors%s;" % (budget_gib, limit_factors, frames_txt))
    print("exact holds %.2f GiB there and reaches %.0f GiB only at about %.0f factors."
          % (exact_per_factor * limit_factors / GiB, budget_gib, budget_gib * GiB / exact_per_factor))
    largest = max(bytes_pts)
    print("largest size run: %d factors, full would need %.2f GiB, exact holds %.3f GiB."
          % (largest[0], largest[1] / GiB, dict(exact_bytes_pts)[largest[0]] / GiB))

# Whole optimizations to convergence: time (compressing + solving), ATE, memory, vs full.
solve_sizes = [f for f in sizes if any(ok(runs.get((k, f))) for k in ("SolveExact", "SolveLossless", "SolveFull"))]
if solve_sizes:
    print("\nwhole optimization to convergence (time = compressing + LM solve; vs full in the same run):")
    print("%7s %9s %-9s %11s %6s %10s %11s %11s %12s %9s" % (
        "frames", "factors", "sampling", "time s", "iters", "ATE mm", "ATE vs full", "time vs full",
        "memory MiB", "mem vs full"))
    for f in solve_sizes:
        full = runs.get(("SolveFull", f))
        for kind, name in (("SolveFull", "full"), ("SolveExact", "exact"), ("SolveLossless", "lossless")):
            b = runs.get((kind, f))
            if not ok(b):
                print("%7d %9s %-9s %11s" % (f, "-", name, "skipped" if b else "-"))
                continue
            rel = lambda key: ("%+.2f %%" % (100.0 * (b[key] / full[key] - 1.0))) if ok(full) else "-"
            print("%7d %9d %-9s %11.3f %6d %10.3f %11s %11s %12.2f %9s" % (
                f, b["factors"], name, b["optimization_s"], b["iterations"], 1e3 * b["ate_rmse_m"],
                rel("ate_rmse_m"), rel("optimization_s"), b["residual_bytes"] / MiB,
                rel("residual_bytes")))

    # Where exact's time and bytes go, against full's whole optimization in the same run.
    print("\nexact (M = 29) against full, per size: its LM alone, its compressing (in full's LM"
          " iterations), what a 95 % cut would leave for compressing, and a factor's bytes:")
    for f in solve_sizes:
        full, ex = runs.get(("SolveFull", f)), runs.get(("SolveExact", f))
        if not (ok(full) and ok(ex)):
            continue
        compress_s = ex["optimization_s"] - ex["solve_s"]
        full_iteration_s = full["solve_s"] / max(1, full["iterations"])
        budget_s = 0.05 * full["optimization_s"] - ex["solve_s"]
        factors = ex["factors"]
        print("%7d frames: LM %.3f s = %.1f %% of full's %.3f s; compressing %.3f s = %.2f of full's"
              " %d LM iterations; a 95 %% cut leaves %.3f s to compress (%.2f ns per row and thread)"
              % (f, ex["solve_s"], 100.0 * ex["solve_s"] / full["optimization_s"],
                 full["optimization_s"], compress_s, compress_s / full_iteration_s,
                 full["iterations"], budget_s,
                 1e9 * budget_s * ex.get("threads", 1) / full["rows"]))
        print("%7s         a factor: %.0f correspondences, %.0f bytes full, %.0f bytes exact (%.3f %%)"
              % ("", ex["correspondences"] / factors, full["residual_bytes"] / factors,
                 ex["residual_bytes"] / factors, 100.0 * ex["residual_bytes"] / full["residual_bytes"]))
PY
