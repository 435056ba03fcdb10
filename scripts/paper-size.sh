#!/usr/bin/env bash
# The paper's problem size on this machine (long: tens of minutes): a simulated drive of 4,540
# frames whose dense graph has about as many factors as the paper's KITTI 00 graph (585,417),
# written to disk by `carat simulate`, then `carat map` from a perturbed start with exact (M = 29)
# and lossless factors, frames read on demand under a memory cap. Writes DIR/paper_size.json:
# per method the whole run's wall time, peak RSS, stage times, iterations, ATE and bytes per
# factor, full sampling's memory computed from its per-factor bytes, and the paper's figures.
#
#   scripts/paper-size.sh [--out DIR] [--frames N] [--laps L] [--circuit-blocks B]
#                         [--overlap X] [--voxel V] [--cap MB] [--threads T] [--no-build]
#
# Defaults: --out paper-size, 4540 frames, 2 laps of a 5-block circuit, overlap 0.2, 0.5 m voxels,
# a 2048 MB frame cap, all cores. The drive is kept in DIR/drive and reused by later runs with the
# same settings. Only needs python3's standard library.
set -euo pipefail
cd "$(dirname "$0")/.."

out=paper-size frames=4540 laps=2 blocks=5 overlap=0.2 voxel=0.5 cap=2048 threads=0 build=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --laps) laps="$2"; shift 2 ;;
    --circuit-blocks) blocks="$2"; shift 2 ;;
    --overlap) overlap="$2"; shift 2 ;;
    --voxel) voxel="$2"; shift 2 ;;
    --cap) cap="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --no-build) build=0; shift ;;
    *) echo "paper-size.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

build_dir="${CARAT_BUILD_DIR:-build}"
if [[ $build == 1 ]]; then
  cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release ${CARAT_CMAKE_ARGS:-} >/dev/null
  cmake --build "$build_dir" --target carat_cli -j"$(nproc)"
fi
carat="$build_dir/apps/carat/carat"
mkdir -p "$out"
drive="$out/drive"
settings="frames=$frames laps=$laps blocks=$blocks"
if [[ ! -f "$drive/settings.txt" || "$(cat "$drive/settings.txt" 2>/dev/null)" != "$settings" ]]; then
  echo "== simulating $frames frames ($laps laps, $blocks blocks) into $drive"
  start=$(date +%s.%N)
  "$carat" simulate --out "$drive" --frames "$frames" --laps "$laps" --circuit-blocks "$blocks" \
    --threads "$threads" >/dev/null
  echo "$settings" >"$drive/settings.txt"
  python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$start" \
    "$(date +%s.%N)" >"$out/simulate_s.txt"
fi

for sampling in exact lossless; do
  echo "== carat map --sampling $sampling"
  start=$(date +%s.%N)
  "$carat" map --frames "$drive" --poses "$drive/poses.txt" --perturb-m 0.1 --perturb-deg 0.5 \
    --rounds 1 --sampling "$sampling" --voxel "$voxel" --overlap "$overlap" \
    --max-frame-memory "$cap" --threads "$threads" --out "$out/$sampling.txt" --json \
    >"$out/map_$sampling.json"
  python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$start" \
    "$(date +%s.%N)" >"$out/wall_$sampling.txt"
done

python3 - "$out" "$settings" "$voxel" "$cap" <<'PY'
import json, os, sys
out, settings, voxel, cap = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
def read(name):
    with open(os.path.join(out, name)) as f:
        return f.read().strip()
summary = {"settings": settings, "voxel_m": voxel, "frame_cap_mb": cap,
           "simulate_s": float(read("simulate_s.txt")) if os.path.exists(os.path.join(out, "simulate_s.txt")) else None,
           "paper": {"frames": 4540, "factors": 585417, "full_memory_gb": [22, 25],
                     "full_hours_128_threads": 13.2, "exact_hours_128_threads": 1.67},
           "methods": {}}
for sampling in ("exact", "lossless"):
    j = json.loads(read(f"map_{sampling}.json"))
    m = {k: j[k] for k in ("frames", "factors", "ate_rmse", "initial_ate_rmse", "iterations",
                           "termination", "time_s", "total_s", "time_breakdown", "memory_bytes",
                           "memory_bytes_per_factor", "correspondence_bytes_per_factor",
                           "peak_rss_bytes", "preprocess_s", "dense_graph_s", "frame_store")
         if k in j}
    m["wall_s"] = float(read(f"wall_{sampling}.txt"))
    # Full sampling would hold every factor's whole GICP block: its bytes as built, summed.
    m["full_memory_bytes"] = j["correspondence_bytes_per_factor"]["mean"] * j["factors"]
    summary["methods"][sampling] = m
e, l = summary["methods"]["exact"], summary["methods"]["lossless"]
summary["exact_ate_vs_lossless_percent"] = 100.0 * (e["ate_rmse"] - l["ate_rmse"]) / l["ate_rmse"]
with open(os.path.join(out, "paper_size.json"), "w") as f:
    json.dump(summary, f, indent=2)
for name, m in summary["methods"].items():
    print(f"{name:9s} {m['frames']} frames, {m['factors']:,} factors: wall {m['wall_s']:.0f} s, "
          f"peak RSS {m['peak_rss_bytes'] / 2**30:.2f} GiB, {m['iterations']} iterations, "
          f"ATE {m['ate_rmse']:.4f} m (start {m['initial_ate_rmse']:.4f} m), "
          f"{m['memory_bytes_per_factor']['mean']:.0f} B/factor; "
          f"full would hold {m['full_memory_bytes'] / 2**30:.1f} GiB")
print(f"exact's ATE vs lossless: {summary['exact_ate_vs_lossless_percent']:+.3f} %")
print(f"wrote {os.path.join(out, 'paper_size.json')}")
PY
