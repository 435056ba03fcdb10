#!/usr/bin/env bash
# End-to-end checks of the carat CLI on simulated drives: simulate, align across cloud formats,
# map (every sampling, loops from a drifting guess), odometry, and their bad input.
# Needs CARAT (the binary); uses CARAT_DATA_DIR for real data when present.
source "$(dirname "$0")/cli_common.sh"

# simulate + map: a simulated drive written to disk, then optimized from perturbed poses.
check simulate 0 "" -- "$CARAT" simulate --out "$scratch/seq" --frames 20 --laps 1
if [[ ! -s "$scratch/seq/000019.bin" ]] || [[ $(grep -c . "$scratch/seq/poses.txt") -ne 20 ]]; then
  echo "FAIL simulate did not write 20 frames and 20 poses"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
# align reads every cloud format: two simulated scans (frames 5 and 6, at a corner, where the
# geometry fixes all six directions) as KITTI .bin, binary PCD and ASCII PLY (the same float32
# points) give the same T_target_source in any pairing.
python3 - "$scratch" <<'PY'
import struct, sys
d = sys.argv[1]
for frame in ("000005", "000006"):
    data = open(f"{d}/seq/{frame}.bin", "rb").read()
    points = [struct.unpack_from("<3f", data, k) for k in range(0, len(data), 16)]
    with open(f"{d}/{frame}.pcd", "wb") as f:
        f.write((f"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {len(points)}\n"
                 f"HEIGHT 1\nPOINTS {len(points)}\nDATA binary\n").encode())
        f.write(b"".join(struct.pack("<3f", *p) for p in points))
    with open(f"{d}/{frame}.ply", "w") as f:
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(points)}\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n")
        f.writelines(" ".join(repr(c) for c in p) + "\n" for p in points)
PY
cp "$scratch/seq/000005.bin" "$scratch/seq/000006.bin" "$scratch/"
for pair in bin:bin pcd:pcd ply:ply pcd:ply; do
  check "align_${pair/:/_}" 0 "" -- "$CARAT" align --target "$scratch/000005.${pair%:*}" --source "$scratch/000006.${pair#*:}" --json
  cp "$scratch/out" "$scratch/align_${pair/:/_}.json"
done
for pair in pcd_pcd ply_ply pcd_ply; do
  expect "align_${pair}_as_bin" "$(python3 -c "
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:])
print(a['T_target_source'] == b['T_target_source'] and a['iterations'] == b['iterations'] and a['points_source'] == b['points_source'])" "$scratch/align_$pair.json" "$scratch/align_bin_bin.json")"
done
check align_unknown_extension 1 "$scratch/tiny.g2o: unsupported file type '.g2o' (expected .pcd, .ply or .bin)" -- "$CARAT" align --target "$scratch/000005.pcd" --source "$scratch/tiny.g2o"
# A longer circuit: around three blocks in a row (about 162 m by 54 m between centre lines).
check simulate_long 0 "" -- "$CARAT" simulate --out "$scratch/seq-long" --frames 40 --laps 1 --circuit-blocks 3
if [[ $(python3 -c "
import sys
x = [float(l.split()[3]) for l in open(sys.argv[1])]
y = [float(l.split()[7]) for l in open(sys.argv[1])]
print(150 < max(x) - min(x) < 163 and 40 < max(y) - min(y) < 55)" "$scratch/seq-long/poses.txt") != "True" ]]; then
  echo "FAIL simulate --circuit-blocks 3 did not drive around three blocks"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check simulate_bad_circuit 2 "" -- "$CARAT" simulate --out "$scratch/never-sim" --circuit-blocks 0
check map_synthetic 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --out "$scratch/map_out.txt" --covariance "$scratch/map_cov.txt" --json
cp "$scratch/out" "$scratch/map.json"
if [[ $(json_field "$scratch/map.json" "j['ate_rmse'] < 0.25 * j['initial_ate_rmse'] and j['frames'] == 20") != "True" ]]; then
  echo "FAIL map on the simulated drive: $(head -c 400 "$scratch/map.json")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
if [[ $(grep -c . "$scratch/map_out.txt") -ne 20 ]]; then echo "FAIL map --out"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
expect map_covariance "$(covariance_file_ok "$scratch/map_cov.txt" 6 $(seq 1 19))"
expect map_covariance_json "$(json_field "$scratch/map.json" "j['covariance_s'] >= 0")"
check map_excess_kernel 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --gre-excess-cauchy 1 --json
cp "$scratch/out" "$scratch/map_excess.json"
if [[ $(json_field "$scratch/map_excess.json" "j['ate_rmse'] < 0.25 * j['initial_ate_rmse'] and j['time_breakdown']['factor_minimum_s'] > 0") != "True" ]]; then
  echo "FAIL map with the excess kernel: $(head -c 400 "$scratch/map_excess.json")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
if [[ $(json_field "$scratch/map.json" "j['time_breakdown']['factor_minimum_s'] == 0") != "True" ]]; then
  echo "FAIL map without the excess kernel reports factor minima"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
# map --sampling full and lossless: the same optimum (lossless rows have the full cost everywhere).
check map_full 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --sampling full --json
cp "$scratch/out" "$scratch/map_full.json"
check map_lossless 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --sampling lossless --json
cp "$scratch/out" "$scratch/map_lossless.json"
full_ate=$(json_field "$scratch/map_full.json" "j['ate_rmse']")
if [[ $(json_field "$scratch/map_lossless.json" "abs(j['ate_rmse'] - $full_ate) <= 1e-9 * $full_ate and j['ate_rmse'] < 0.25 * j['initial_ate_rmse'] and j['method'] == 'gre_lossless'") != "True" ]]; then
  echo "FAIL map --sampling lossless differs from full: $(head -c 300 "$scratch/map_lossless.json")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check map_pgo 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --method pgo --json
# Frames read on demand under a 6 MB cap (about 11 of these frames): the same trajectory, the
# store's counts in the JSON; a cap below one pair is refused up front; a frame that cannot be read
# midway fails the run by name and leaves no output.
check map_streamed 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --out "$scratch/map_streamed.txt" --max-frame-memory 6 --json
expect map_streamed_same "$(cmp -s "$scratch/map_out.txt" "$scratch/map_streamed.txt" && echo True)"
expect map_streamed_json "$(json_field "$scratch/out" "(lambda s: s['max_bytes'] == 6 * 2**20 and s['peak_bytes'] <= s['max_bytes'] and s['loads'] > 20 and s['evictions'] > 0 and s['hits'] + s['loads'] == s['requests'])(j['frame_store']) and j['peak_rss_bytes'] > 0")"
check map_streamed_small_cap 2 "--max-frame-memory 1 MB cannot hold one pair of frames: 000000.bin and 000001.bin take" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --max-frame-memory 1 --out "$scratch/never.txt"
cp -r "$scratch/seq" "$scratch/midway_seq"
head -c 1001 "$scratch/seq/000002.bin" >"$scratch/midway_seq/000014.bin"
check map_streamed_bad_frame 1 "midway_seq/000014.bin: 1001 bytes is not a whole number of 16-byte records" -- "$CARAT" map --frames "$scratch/midway_seq" --poses "$scratch/seq/poses.txt" --max-frame-memory 6 --out "$scratch/never.txt"
check map_streamed_nan_cap 2 "--max-frame-memory" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --max-frame-memory nan
# A linear system over --max-system-memory ends the run with its estimate and no output.
check map_system_over_cap 1 "carat: error: global registration: the solve failed: linear solver: sparse Cholesky of the whole system needs about" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --max-system-memory 0.001 --out "$scratch/never.txt"
expect map_system_over_cap_no_out "$([[ ! -e "$scratch/never.txt" ]] && echo True)"
check map_system_cap_negative 2 "--max-system-memory: must be 0 (80 % of the memory available) or a finite number in [0.001, 1e+09], got '-1'" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --max-system-memory -1
# Bad input: clear one-line errors, exit 1, no output file left behind.
mkdir -p "$scratch/empty_frames"
check map_empty_folder 1 "empty_frames: no frames" -- "$CARAT" map --frames "$scratch/empty_frames" --poses "$scratch/seq/poses.txt" --out "$scratch/never.txt"
head -n 19 "$scratch/seq/poses.txt" >"$scratch/short.txt"
check map_count_mismatch 1 "--poses $scratch/short.txt has 19 poses but --frames $scratch/seq holds 20 frames" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/short.txt" --out "$scratch/never.txt"
sed '3s/^[^ ]*/nan/' "$scratch/seq/poses.txt" >"$scratch/nan.txt"
check map_nan_pose 1 "nan.txt:3:" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/nan.txt" --out "$scratch/never.txt"
cp -r "$scratch/seq" "$scratch/small_seq"
head -c 320 "$scratch/seq/000004.bin" >"$scratch/small_seq/000004.bin"
check map_tiny_frame 1 "000004.bin: only 20 points" -- "$CARAT" map --frames "$scratch/small_seq" --poses "$scratch/seq/poses.txt" --out "$scratch/never.txt"
head -c 1001 "$scratch/seq/000002.bin" >"$scratch/small_seq/000004.bin"
check map_truncated_frame 1 "000004.bin" -- "$CARAT" map --frames "$scratch/small_seq" --poses "$scratch/seq/poses.txt" --out "$scratch/never.txt"
if [[ -e "$scratch/never.txt" ]]; then echo "FAIL map left an output file after an error"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
awk 'NR == 11 { $4 += 500 } { print }' "$scratch/seq/poses.txt" >"$scratch/far.txt"
check map_disconnected 1 "pair (9, 10) has only 0 correspondences" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/far.txt" --out "$scratch/never.txt"
check map_missing_poses 1 "nope.txt" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/nope.txt"
: >"$scratch/empty_poses.txt"
check map_empty_poses 1 "empty_poses.txt: no KITTI poses" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/empty_poses.txt"
check map_missing_frames 1 "nowhere: not a folder of frames" -- "$CARAT" map --frames "$scratch/nowhere" --poses "$scratch/seq/poses.txt"
# map from an odometry guess whose heading drifts by 10 degrees per 100 m (60 frames, 2 laps):
# loops closed first (the default with --initial), then the dense graph; without them the report
# says that no loop was searched.
check simulate_drift 0 "" -- "$CARAT" simulate --out "$scratch/drift" --frames 60 --drift-heading 0.1
check map_loops 0 "" -- "$CARAT" map --frames "$scratch/drift" --initial "$scratch/drift/initial.txt" --poses "$scratch/drift/poses.txt" --rounds 1 --out "$scratch/drift_out.txt" --json
if [[ $(json_field "$scratch/out" "j['start'] == 'initial' and j['loops']['ran'] and j['loops']['accepted'] >= 20 and j['loops']['candidates'] >= j['loops']['accepted'] and j['loops']['pgo']['termination'] != 'FAILURE' and j['initial_ate_rmse'] > 2.0 and j['loops']['ate_rmse'] < 0.25 and j['ate_rmse'] < 0.25") != "True" ]] || [[ $(grep -c . "$scratch/drift_out.txt") -ne 60 ]]; then
  echo "FAIL map --initial with loops: $(head -c 600 "$scratch/out")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check map_no_loops 0 "" -- "$CARAT" map --frames "$scratch/drift" --initial "$scratch/drift/initial.txt" --poses "$scratch/drift/poses.txt" --rounds 1 --no-loops
grep -q "loops: not searched" "$scratch/out" || { echo "FAIL map --no-loops does not say that no loop was searched"; fail=$((fail + 1)); }
check map_initial_count 1 "--initial $scratch/short_initial.txt has 59 poses but --frames $scratch/drift holds 60 frames" -- bash -c "head -n 59 '$scratch/drift/initial.txt' > '$scratch/short_initial.txt' && exec '$CARAT' map --frames '$scratch/drift' --initial '$scratch/short_initial.txt'"
check map_no_start 2 "give --poses (a reference trajectory), --initial" -- "$CARAT" map --frames "$scratch/drift"
check map_initial_perturb 2 "--perturb-m does not apply with --initial" -- "$CARAT" map --frames "$scratch/drift" --initial "$scratch/drift/initial.txt" --perturb-m 1
check map_no_loops_alone 2 "--no-loops does not apply without --initial" -- "$CARAT" map --frames "$scratch/drift" --poses "$scratch/drift/poses.txt" --no-loops
# odometry from the scans alone (50 frames, one lap, 4 m apart), then its ATE.
check simulate_lap 0 "" -- "$CARAT" simulate --out "$scratch/lap" --frames 50 --laps 1
check odometry 0 "" -- "$CARAT" odometry --frames "$scratch/lap" --out "$scratch/lap_odometry.txt" --json
if [[ $(json_field "$scratch/out" "j['frames'] == 50 and j['steps_not_converged'] == 0") != "True" ]] || [[ $(grep -c . "$scratch/lap_odometry.txt") -ne 50 ]]; then
  echo "FAIL odometry: $(head -c 400 "$scratch/out")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check odometry_ate 0 "" -- "$CARAT" ate --estimate "$scratch/lap_odometry.txt" --reference "$scratch/lap/poses.txt" --json
if [[ $(json_field "$scratch/out" "j['rmse'] < 0.2") != "True" ]]; then
  echo "FAIL odometry drifts: $(head -c 300 "$scratch/out")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check odometry_into_frames 2 "" -- "$CARAT" odometry --frames "$scratch/lap" --out "$scratch/lap/000003.bin"
check map_unknown_flag 2 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --frobnicate
check map_out_of_range 2 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --residuals 5
check simulate_bad_out 1 "" -- "$CARAT" simulate --out /proc/carat-cannot-write --frames 4


# More bad input for simulate and map.
check simulate_out_of_range 2 "" -- "$CARAT" simulate --out "$scratch/x" --frames 1
check paper_unknown_flag 2 "" -- "$CARAT" paper --fast
check demo_out_of_range 2 "" -- "$CARAT" demo --residuals 10
cp -r "$scratch/seq" "$scratch/nan_seq"
python3 -c "import struct,sys; f=open(sys.argv[1],'r+b'); f.seek(16*5); f.write(struct.pack('<3f', float('nan'), 0, 0))" "$scratch/nan_seq/000003.bin"
check map_non_finite_point 1 "000003.bin: point 5 is not finite" -- "$CARAT" map --frames "$scratch/nan_seq" --poses "$scratch/seq/poses.txt" --out "$scratch/never.txt"
check map_drop_non_finite 0 "" -- "$CARAT" map --frames "$scratch/nan_seq" --poses "$scratch/seq/poses.txt" --drop-non-finite --rounds 1
check map_bad_sampling 2 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --sampling most
if [[ -f "${CARAT_DATA_DIR:-}/kitti07_seq5/graph.txt" ]]; then
  check map_kitti07 0 "" -- "$CARAT" map --frames "$CARAT_DATA_DIR/kitti07_seq5" --poses "$CARAT_DATA_DIR/kitti07_seq5/graph.txt" --poses-format graph --perturb-m 0.3 --perturb-deg 3 --json
  cp "$scratch/out" "$scratch/map07.json"
  if [[ $(json_field "$scratch/map07.json" "j['ate_rmse'] < 0.02 and j['ate_rotation_rmse_deg'] < 0.2 and j['frames'] == 5") != "True" ]]; then
    echo "FAIL map on kitti07_seq5: $(head -c 600 "$scratch/map07.json")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
fi

echo "$pass passed, $fail failed"
[[ $fail -eq 0 ]]
