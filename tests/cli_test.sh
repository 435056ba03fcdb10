#!/usr/bin/env bash
# End-to-end checks of the carat CLI: outputs, exit codes, one-line errors, no partial files.
# Needs CARAT (the binary); uses CARAT_DATA_DIR for real data when present.
source "$(dirname "$0")/cli_common.sh"

# --version: the version of CMakeLists.txt's project(VERSION).
project_version=$(sed -n 's/^project(carat VERSION \([0-9.]*\).*/\1/p' "$(dirname "$0")/../CMakeLists.txt")
check version 0 "" -- "$CARAT" --version
if [[ -z $project_version || "$(cat "$scratch/out")" != "carat $project_version" ]]; then
  echo "FAIL --version printed '$(cat "$scratch/out")', expected 'carat $project_version'"; fail=$((fail + 1))
else pass=$((pass + 1)); fi

# demo: the dense-graph job on a small synthetic world; report, JSON fields, files.
check demo_runs 0 "" -- "$CARAT" demo --frames 24 --out "$scratch/demo-text"
grep -q "GRE exact (M=29)" "$scratch/out" || { echo "FAIL demo report lacks the GRE exact row"; fail=$((fail + 1)); }
grep -qF "GRE: correspondences searched in up to 2 rounds, excess Cauchy kernel 0.3 (--paper: the paper's setting)" "$scratch/out" || { echo "FAIL demo report does not state the GRE setting"; fail=$((fail + 1)); }
check demo_json 0 "" -- "$CARAT" demo --frames 24 --json --out "$scratch/demo"
cp "$scratch/out" "$scratch/demo.json"
demo_ok=$(json_field "$scratch/demo.json" "all(k in m for m in j['methods'] for k in ('ate_mean','ate_std','ate_rmse','time_s','time_breakdown','memory_bytes','iterations')) and j['frames'] == 24 and j['factors'] >= 23 and [m['method'] for m in j['methods']] == ['pgo_identity','pgo_hessian','gre_full','gre_exact','gre_random','gre_lossless']")
if [[ $demo_ok != "True" ]]; then echo "FAIL demo JSON fields: $demo_ok"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
demo_better=$(json_field "$scratch/demo.json" "all(m['ate_rmse'] < j['initial_ate_rmse'] for m in j['methods'][:4])")
if [[ $demo_better != "True" ]]; then echo "FAIL demo: a method did not improve on the initial guess"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
# Per-factor memory (mean, min, max) and the time breakdown's stages, per method.
demo_memory=$(json_field "$scratch/demo.json" "all(abs(m['memory_bytes_per_factor']['mean'] * j['factors'] - m['memory_bytes']) <= 1e-6 * m['memory_bytes'] and m['memory_bytes_per_factor']['min'] <= m['memory_bytes_per_factor']['max'] for m in j['methods'] if m['method'].startswith('gre')) and all(m['correspondence_bytes_per_factor']['max'] > 1000 * 29 for m in j['methods'] if m['method'].startswith('gre')) and [m for m in j['methods'] if m['method'] == 'gre_lossless'][0]['memory_bytes_per_factor']['max'] <= 900")
if [[ $demo_memory != "True" ]]; then echo "FAIL demo per-factor memory: $demo_memory"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
demo_setting=$(json_field "$scratch/demo.json" "j['gre_rounds'] == 2 and j['gre_excess_cauchy'] == 0.3 and j['gre_cauchy'] == 0 and j['pgo_cauchy'] == 1 and all(m['time_breakdown']['factor_minimum_s'] > 0 for m in j['methods'] if m['method'] in ('gre_full', 'gre_exact'))")
if [[ $demo_setting != "True" ]]; then echo "FAIL demo JSON: default GRE setting: $demo_setting"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check demo_paper 0 "" -- "$CARAT" demo --frames 24 --paper --json --out "$scratch/demo-paper"
demo_paper=$(json_field "$scratch/out" "(lambda m: j['gre_rounds'] == 1 and j['gre_excess_cauchy'] == 0 and j['gre_cauchy'] == 0 and m['gre_full']['time_breakdown']['factor_minimum_s'] == 0 and abs(m['gre_lossless']['ate_rmse'] - m['gre_full']['ate_rmse']) <= 1e-9 * m['gre_full']['ate_rmse'])({m['method']: m for m in j['methods']})")
if [[ $demo_paper != "True" ]]; then echo "FAIL demo --paper: $demo_paper"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check demo_whole_kernel 0 "" -- "$CARAT" demo --frames 24 --gre-cauchy 1 --json --out "$scratch/demo-whole"
demo_whole=$(json_field "$scratch/out" "j['gre_cauchy'] == 1 and j['gre_excess_cauchy'] == 0 and j['gre_rounds'] == 2")
if [[ $demo_whole != "True" ]]; then echo "FAIL demo --gre-cauchy turns the excess kernel off: $demo_whole"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
demo_stages=$(json_field "$scratch/demo.json" "all(set(m['time_breakdown']) >= {'correspondences_s','compression_s','linearization_s','cost_evaluation_s','linear_solve_s','optimization_s'} for m in j['methods'] if m['method'].startswith('gre')) and all(set(m['time_breakdown']) >= {'registration_s','linearization_s','cost_evaluation_s','linear_solve_s'} for m in j['methods'] if m['method'].startswith('pgo'))")
if [[ $demo_stages != "True" ]]; then echo "FAIL demo time breakdown stages"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
# The drift-model start instead of GICP odometry.
check demo_drift 0 "" -- "$CARAT" demo --frames 24 --initial drift --json --out "$scratch/demo-drift"
# Its heading drifts by 10 degrees per 100 m: loops are closed (every accepted one true) before
# the dense graph, and every method ends below 0.25 m.
if [[ $(json_field "$scratch/out" "j['initial'] == 'drift' and j['loops']['ran'] and j['loops']['accepted'] >= 8 and j['loops']['accepted_correct'] == j['loops']['accepted'] and j['loops']['ate_rmse_after'] < 0.1 * j['loops']['ate_rmse_before'] and j['initial_ate_rmse'] > 1.0 and all(m['ate_rmse'] < 0.25 for m in j['methods'] if m['method'] != 'gre_random')") != "True" ]]; then
  echo "FAIL demo --initial drift: $(head -c 600 "$scratch/out")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
# Progress bars: drawn on a terminal (a pseudo-terminal from util-linux's script), never in a pipe.
if command -v script >/dev/null; then
  script -qec "'$CARAT' demo --frames 100 --out '$scratch/demo-tty'" /dev/null >"$scratch/tty.log" 2>&1 || true
  if ! grep -q "registering pairs (GICP) *\[#" "$scratch/tty.log"; then
    echo "FAIL demo on a terminal drew no progress bar"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
  "$CARAT" demo --frames 100 --out "$scratch/demo-pipe" >/dev/null 2>"$scratch/pipe.log"
  if grep -q "\[#" "$scratch/pipe.log"; then echo "FAIL progress bar drawn into a file"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
fi
# GRE lossless: the full factors' optimum (same ATE to 1e-9 relative) in < 0.5 % of their memory.
demo_lossless=$(json_field "$scratch/demo.json" "(lambda m: abs(m['gre_lossless']['ate_rmse'] - m['gre_full']['ate_rmse']) <= 1e-9 * m['gre_full']['ate_rmse'] and m['gre_lossless']['memory_bytes'] * 200 < m['gre_full']['memory_bytes'] and m['gre_lossless']['iterations'] == m['gre_full']['iterations'])({m['method']: m for m in j['methods']})")
if [[ $demo_lossless != "True" ]]; then echo "FAIL demo: GRE lossless is not the full optimum in < 0.5 % of the memory"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
for f in ground_truth_kitti.txt ground_truth_tum.txt initial_kitti.txt gre_exact_kitti.txt gre_exact_tum.txt pgo_hessian_tum.txt trajectories_before.svg trajectories_after.svg graph.svg demo.json; do
  if [[ ! -s "$scratch/demo/$f" ]]; then echo "FAIL demo did not write $f"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
done
if [[ $(grep -c . "$scratch/demo/gre_exact_kitti.txt") -ne 24 ]]; then echo "FAIL demo trajectory has the wrong length"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
grep -q "<svg" "$scratch/demo/graph.svg" && grep -q "<line" "$scratch/demo/graph.svg" || { echo "FAIL graph.svg has no edges"; fail=$((fail + 1)); }

# solve-g2o on the tiny graph from cli_common.sh.
check solve_g2o_json 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --json --out "$scratch/solved.g2o"
cp "$scratch/out" "$scratch/solve.json"
for key in vertices edges initial_cost final_cost iterations termination time_s time_breakdown; do
  if [[ $(json_field "$scratch/solve.json" "'$key' in j") != "True" ]]; then
    echo "FAIL solve-g2o --json lacks $key"; fail=$((fail + 1))
  fi
done
if [[ $(json_field "$scratch/solve.json" "j['final_cost'] < 1e-12 and j['vertices'] == 3 and j['edges'] == 3") != "True" ]]; then
  echo "FAIL solve-g2o did not reach zero cost on a consistent graph"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
if ! awk '$1 == "VERTEX_SE3:QUAT" && $2 == 2 { exit !(($3 - 2) ^ 2 < 1e-12) }' "$scratch/solved.g2o"; then
  echo "FAIL --out did not write the solved graph"; fail=$((fail + 1))
else pass=$((pass + 1)); fi

# solve-g2o on a 2D graph: a square of four unit odometry steps and quarter turns, the second
# vertex off by 0.3 m; --out writes VERTEX_SE2 records at the solution.
cat >"$scratch/square2d.g2o" <<'G2O'
VERTEX_SE2 0 0 0 0
VERTEX_SE2 1 1.3 0 1.5707963267948966
VERTEX_SE2 2 1 1 3.141592653589793
VERTEX_SE2 3 0 1 -1.5707963267948966
EDGE_SE2 0 1 1 0 1.5707963267948966 1 0 0 1 0 1
EDGE_SE2 1 2 1 0 1.5707963267948966 1 0 0 1 0 1
EDGE_SE2 2 3 1 0 1.5707963267948966 1 0 0 1 0 1
EDGE_SE2 3 0 1 0 1.5707963267948966 1 0 0 1 0 1
G2O
check solve_g2o_2d 0 "" -- "$CARAT" solve-g2o "$scratch/square2d.g2o" --json --out "$scratch/square2d_solved.g2o"
cp "$scratch/out" "$scratch/square2d.json"
if [[ $(json_field "$scratch/square2d.json" "j['dimension'] == 2 and j['vertices'] == 4 and j['edges'] == 4 and j['final_cost'] < 1e-12 < j['initial_cost']") != "True" ]]; then
  echo "FAIL solve-g2o did not solve the 2D square"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
if ! awk '$1 == "VERTEX_SE2" && $2 == 1 { exit !(($3 - 1) ^ 2 < 1e-12 && $4 ^ 2 < 1e-12) }' "$scratch/square2d_solved.g2o"; then
  echo "FAIL --out did not write the solved 2D graph"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
printf 'VERTEX_SE2 0 0 0 0\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n' >"$scratch/mixed.g2o"
check mixed_dimensions 1 "mixed.g2o:2: 3D record VERTEX_SE3:QUAT in a 2D graph (line 1 holds VERTEX_SE2)" -- "$CARAT" solve-g2o "$scratch/mixed.g2o"

# Bad input: one-line message naming the input, exit 1, no output file left behind.
check missing_file 1 "missing.g2o: no such file" -- "$CARAT" solve-g2o "$scratch/missing.g2o" --out "$scratch/o1.g2o"
: >"$scratch/empty.g2o"
check empty_file 1 "empty.g2o: no VERTEX_SE3:QUAT records" -- "$CARAT" solve-g2o "$scratch/empty.g2o" --out "$scratch/o2.g2o"
head -c 150 "$scratch/tiny.g2o" >"$scratch/truncated.g2o"
check truncated_file 1 "truncated.g2o:4: EDGE_SE3:QUAT needs 30 numbers, found 11" -- "$CARAT" solve-g2o "$scratch/truncated.g2o" --out "$scratch/o3.g2o"
sed 's/^VERTEX_SE3:QUAT 1 0.9/VERTEX_SE3:QUAT 1 nan/' "$scratch/tiny.g2o" >"$scratch/nan.g2o"
check non_finite 1 "nan.g2o:2: x is not finite" -- "$CARAT" solve-g2o "$scratch/nan.g2o" --out "$scratch/o4.g2o"
check directory 1 "is a directory" -- "$CARAT" solve-g2o "$scratch" --out "$scratch/o5.g2o"
for f in o1 o2 o3 o4 o5; do
  [[ -e "$scratch/$f.g2o" ]] && { echo "FAIL an output file was left behind: $f.g2o"; fail=$((fail + 1)); }
done
ls "$scratch" | grep -q "\.tmp-" && { echo "FAIL a temporary file was left behind"; fail=$((fail + 1)); }

# Usage errors exit 2.
check unknown_flag 2 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --bogus
check out_of_range 2 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --threads 0
check bad_method 2 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --method newton
check bad_growth 2 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --trust-region-growth 0.5
check ceres_like_lm 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --json --no-factor-reuse --trust-region-growth 3
cp "$scratch/out" "$scratch/ceres_like.json"
if [[ $(json_field "$scratch/ceres_like.json" "j['reused_factorizations'] == 0 and j['refused_reuses'] == 0 and j['final_cost'] < 1e-12") != "True" ]]; then
  echo "FAIL solve-g2o --no-factor-reuse"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
check no_subcommand 2 "" -- "$CARAT"
check demo_bad_frames 2 "" -- "$CARAT" demo --frames 3
check demo_two_kernels 2 "excludes" -- "$CARAT" demo --frames 24 --gre-cauchy 1 --gre-excess-cauchy 1
check demo_paper_and_rounds 2 "excludes" -- "$CARAT" demo --frames 24 --paper --rounds 3

# coreset-check: exact and of the requested size; JSON has the documented fields.
check coreset_check 0 "" -- "$CARAT" coreset-check --rows 5000 --target 29 --trials 3 --json
cp "$scratch/out" "$scratch/coreset.json"
for key in rows dim target clusters trials rows_out_min rows_out_max max_rel_error_H max_rel_error_b max_rel_error_c median_ms reference_median_ms; do
  if [[ $(json_field "$scratch/coreset.json" "'$key' in j") != "True" ]]; then
    echo "FAIL coreset-check --json lacks $key"; fail=$((fail + 1))
  fi
done
if [[ $(json_field "$scratch/coreset.json" "j['rows_out_min'] == 29 and j['rows_out_max'] == 29 and max(j['max_rel_error_H'], j['max_rel_error_b'], j['max_rel_error_c']) <= 1e-12") != "True" ]]; then
  echo "FAIL coreset-check: wrong size or not exact"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
check coreset_target_too_small 2 "carat: usage error: --target 10 is below the minimum of 29 rows for --dim 6" -- "$CARAT" coreset-check --rows 100 --target 10
check coreset_bad_rows 2 "" -- "$CARAT" coreset-check --rows 0

# align: bad input.
check align_missing 1 "missing.bin: no such file" -- "$CARAT" align --target "$scratch/missing.bin" --source "$scratch/missing.bin"
printf 'abcdefghij' >"$scratch/ten.bin"
check align_truncated 1 "ten.bin: 10 bytes is not a whole number of 16-byte records" -- "$CARAT" align --target "$scratch/ten.bin" --source "$scratch/ten.bin"
: >"$scratch/empty.bin"
check align_empty 1 "empty.bin" -- "$CARAT" align --target "$scratch/empty.bin" --source "$scratch/empty.bin"
python3 -c "import struct,sys; open(sys.argv[1],'wb').write(struct.pack('<3f', 1, 2, 3) * 50 + struct.pack('<3f', float('inf'), 0, 0))" "$scratch/inf.bin"
check align_non_finite 1 "inf.bin" -- "$CARAT" align --target "$scratch/inf.bin" --source "$scratch/inf.bin" --bin-format xyz
check align_unknown_flag 2 "" -- "$CARAT" align --target "$scratch/inf.bin" --source "$scratch/inf.bin" --fast
python3 -c "import struct,sys; open(sys.argv[1],'wb').write(struct.pack('<12f', *[0.0]*12))" "$scratch/few.bin"
check align_too_few_points 1 "few.bin: only 1 points after downsampling (at least 29 are needed)" -- "$CARAT" align --target "$scratch/few.bin" --source "$scratch/few.bin"
check align_wrong_type 1 "unsupported file type" -- "$CARAT" align --target "$scratch/tiny.g2o" --source "$scratch/tiny.g2o"
check align_bad_voxel 2 "" -- "$CARAT" align --target a.bin --source b.bin --voxel -1

# Real data, when present.
if [[ -f "${CARAT_DATA_DIR:-}/posegraph/sphere2500.g2o" ]]; then
  check sphere2500 0 "" -- "$CARAT" solve-g2o "$CARAT_DATA_DIR/posegraph/sphere2500.g2o" --json
  cp "$scratch/out" "$scratch/sphere.json"
  # Ceres 2.1 reaches 675.608 on this file with the same cost function.
  if [[ $(json_field "$scratch/sphere.json" "abs(j['final_cost'] - 675.6078) < 1e-2 and j['termination'] == 'CONVERGENCE'") != "True" ]]; then
    echo "FAIL sphere2500 final cost $(json_field "$scratch/sphere.json" "j['final_cost']")"; fail=$((fail + 1))
  else pass=$((pass + 1)); fi
  check align_kitti00 0 "" -- "$CARAT" align --target "$CARAT_DATA_DIR/kitti00_pair/000000.bin" --source "$CARAT_DATA_DIR/kitti00_pair/000001.bin" --bin-format xyz --json
  cp "$scratch/out" "$scratch/align.json"
  if [[ $(json_field "$scratch/align.json" "j['converged'] and abs(j['T_target_source'][0][3] - 0.690) < 0.01") != "True" ]]; then
    echo "FAIL align on kitti00_pair"; fail=$((fail + 1))
  else pass=$((pass + 1)); fi
  # 2D: manhattan has no vertices (initial poses composed from odometry), intel has them.
  check manhattan 0 "" -- "$CARAT" solve-g2o "$CARAT_DATA_DIR/posegraph/manhattan.g2o" --json
  cp "$scratch/out" "$scratch/manhattan.json"
  if [[ $(json_field "$scratch/manhattan.json" "abs(j['final_cost'] - 1774.52) < 1e-2 and j['vertices'] == 3500 and j['termination'] == 'CONVERGENCE'") != "True" ]]; then
    echo "FAIL manhattan final cost $(json_field "$scratch/manhattan.json" "j['final_cost']")"; fail=$((fail + 1))
  else pass=$((pass + 1)); fi
  check cubicle_indefinite 1 "cubicle.g2o:5753: information matrix" -- "$CARAT" solve-g2o "$CARAT_DATA_DIR/posegraph/cubicle.g2o"
  check cubicle_repaired 0 "" -- "$CARAT" solve-g2o "$CARAT_DATA_DIR/posegraph/cubicle.g2o" --repair-information --json
  cp "$scratch/out" "$scratch/cubicle.json"
  if [[ $(json_field "$scratch/cubicle.json" "j['termination'] == 'CONVERGENCE' and j['repaired_information'] == 5021 and j['final_cost'] < 1e-3 * j['initial_cost']") != "True" ]]; then
    echo "FAIL cubicle with --repair-information"; fail=$((fail + 1))
  else pass=$((pass + 1)); fi
else
  echo "skipping real-data CLI checks: ${CARAT_DATA_DIR:-<unset>}/posegraph not found"
fi

# ate: absolute trajectory error between small trajectory files.
cat >"$scratch/ref.kitti" <<'KITTI'
1 0 0 0 0 1 0 0 0 0 1 0
0 -1 0 2 1 0 0 1 0 0 1 0.5
1 0 0 4 0 0 -1 -1 0 1 0 1
1 0 0 3 0 1 0 5 0 0 1 -2
KITTI
# The same poses shifted by (0.3, -1.2, 0.4), |shift| = 1.3.
awk '{ $4 += 0.3; $8 -= 1.2; $12 += 0.4; print }' "$scratch/ref.kitti" >"$scratch/shifted.kitti"
check ate_identical 0 "" -- "$CARAT" ate --estimate "$scratch/ref.kitti" --reference "$scratch/ref.kitti" --json
cp "$scratch/out" "$scratch/ate_same.json"
if [[ $(json_field "$scratch/ate_same.json" "j['rmse'] < 1e-9 and j['max'] < 1e-9 and j['num_poses'] == 4 and j['association'] == 'index'") != "True" ]]; then
  echo "FAIL ate of a trajectory with itself is not 0"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
for key in rmse mean median std min max rotation_rmse_deg rotation_mean_deg rotation_max_deg num_poses T_reference_estimate; do
  if [[ $(json_field "$scratch/ate_same.json" "'$key' in j") != "True" ]]; then
    echo "FAIL ate --json lacks $key"; fail=$((fail + 1))
  fi
done
check ate_shift_no_align 0 "" -- "$CARAT" ate --estimate "$scratch/shifted.kitti" --reference "$scratch/ref.kitti" --no-align --json
cp "$scratch/out" "$scratch/ate_shift.json"
if [[ $(json_field "$scratch/ate_shift.json" "abs(j['rmse'] - 1.3) < 1e-9 and abs(j['median'] - 1.3) < 1e-9 and j['std'] < 1e-9 and not j['aligned']") != "True" ]]; then
  echo "FAIL ate --no-align of a shifted copy: rmse $(json_field "$scratch/ate_shift.json" "j['rmse']"), expected 1.3"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
check ate_shift_aligned 0 "" -- "$CARAT" ate --estimate "$scratch/shifted.kitti" --reference "$scratch/ref.kitti" --json
cp "$scratch/out" "$scratch/ate_aligned.json"
if [[ $(json_field "$scratch/ate_aligned.json" "j['rmse'] < 1e-9 and abs(j['T_reference_estimate'][1][3] - 1.2) < 1e-9") != "True" ]]; then
  echo "FAIL ate with alignment of a shifted copy is not 0"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
check ate_text 0 "" -- "$CARAT" ate --estimate "$scratch/shifted.kitti" --reference "$scratch/ref.kitti" --no-align
grep -q "rmse 1.300000" "$scratch/out" || { echo "FAIL ate text output lacks 'rmse 1.300000'"; fail=$((fail + 1)); }
# TUM: paired by stamp (0.004 s apart, one extra reference pose); graph: by index.
printf '# t x y z qx qy qz qw\n0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n2.0 1 1 0 0 0 0 1\n3.0 0 1 1 0 0 0 1\n' >"$scratch/ref.tum"
printf '0.004 0 0 0 0 0 0 1\r\n2.004 1 1 0 0 0 0 1\r\n3.004 0 1 1 0 0 0 1\r\n' >"$scratch/est.tum"
check ate_tum 0 "" -- "$CARAT" ate --estimate "$scratch/est.tum" --reference "$scratch/ref.tum" --format tum --json
cp "$scratch/out" "$scratch/ate_tum.json"
if [[ $(json_field "$scratch/ate_tum.json" "j['num_poses'] == 3 and j['association'] == 'stamp' and j['rmse'] < 1e-9") != "True" ]]; then
  echo "FAIL ate on TUM files did not pair 3 poses by stamp"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
check ate_tum_no_match 1 "est.tum: none of its 3 stamps" -- "$CARAT" ate --estimate "$scratch/est.tum" --reference "$scratch/ref.tum" --format tum --max-difference 0.001
printf 'v0 0 0 0 0 0 0 1\nv1 2 1 0.5 0 0 0.7071067811865476 0.7071067811865476\nv2 4 -1 1 0 0 0 1\nv3 3 5 -2 0 0 0 1\n' >"$scratch/graph.txt"
check ate_graph_vs_kitti 0 "" -- "$CARAT" ate --estimate "$scratch/graph.txt" --format graph --reference "$scratch/shifted.kitti" --reference-format kitti --no-align --json
cp "$scratch/out" "$scratch/ate_graph.json"
if [[ $(json_field "$scratch/ate_graph.json" "abs(j['rmse'] - 1.3) < 1e-9") != "True" ]]; then
  echo "FAIL ate graph vs kitti: rmse $(json_field "$scratch/ate_graph.json" "j['rmse']"), expected 1.3"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
# Bad input: one-line messages naming the files (and the line); usage errors exit 2.
head -n 3 "$scratch/ref.kitti" >"$scratch/three.kitti"
check ate_count_mismatch 1 "three.kitti has 3 poses but $scratch/ref.kitti has 4" -- "$CARAT" ate --estimate "$scratch/three.kitti" --reference "$scratch/ref.kitti"
printf '1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n' >"$scratch/malformed.kitti"
check ate_malformed 1 "malformed.kitti:2: KITTI pose (3x4 row-major [R|t]) needs 12 fields, found 11" -- "$CARAT" ate --estimate "$scratch/malformed.kitti" --reference "$scratch/ref.kitti"
printf '0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 2\n' >"$scratch/badquat.tum"
check ate_bad_quaternion 1 "badquat.tum:2: quaternion is not normalized" -- "$CARAT" ate --estimate "$scratch/badquat.tum" --reference "$scratch/ref.tum" --format tum
check ate_missing 1 "nope.kitti: no such file" -- "$CARAT" ate --estimate "$scratch/nope.kitti" --reference "$scratch/ref.kitti"
: >"$scratch/empty.kitti"
check ate_empty 1 "empty.kitti: no KITTI poses" -- "$CARAT" ate --estimate "$scratch/empty.kitti" --reference "$scratch/ref.kitti"
head -n 2 "$scratch/ref.kitti" >"$scratch/two.kitti"
check ate_too_few_to_align 1 "alignment needs at least 3 (use --no-align)" -- "$CARAT" ate --estimate "$scratch/two.kitti" --reference "$scratch/two.kitti"
check ate_bad_format 2 "" -- "$CARAT" ate --estimate "$scratch/ref.kitti" --reference "$scratch/ref.kitti" --format euroc
check ate_no_reference 2 "" -- "$CARAT" ate --estimate "$scratch/ref.kitti"
if [[ -f "${CARAT_DATA_DIR:-}/kitti07_seq5/graph.txt" ]]; then
  check ate_real_graph 0 "" -- "$CARAT" ate --estimate "$CARAT_DATA_DIR/kitti07_seq5/graph.txt" --reference "$CARAT_DATA_DIR/kitti07_seq5/graph.txt" --format graph --json
  cp "$scratch/out" "$scratch/ate_real.json"
  if [[ $(json_field "$scratch/ate_real.json" "j['num_poses'] == 5 and j['rmse'] < 1e-9") != "True" ]]; then
    echo "FAIL ate of kitti07_seq5/graph.txt with itself"; fail=$((fail + 1))
  else pass=$((pass + 1)); fi
fi

# Degenerate and disconnected input: a single plane cannot fix an alignment; a pose graph with
# a part not linked to a fixed vertex has undetermined poses.
python3 - "$scratch" <<'PY'
import random, struct, sys
random.seed(1)
for name in ("plane_a.bin", "plane_b.bin"):
    with open(sys.argv[1] + "/" + name, "wb") as f:
        for _ in range(20000):
            f.write(struct.pack("<3f", random.uniform(-20, 20), random.uniform(-20, 20), random.gauss(0, 0.01)))
PY
check align_planar 1 "constrain only 3 of 6 degrees of freedom" -- "$CARAT" align --target "$scratch/plane_a.bin" --source "$scratch/plane_b.bin" --bin-format xyz
cat >"$scratch/disconnected.g2o" <<'G2O'
VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1
VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1
VERTEX_SE3:QUAT 2 5 0 0 0 0 0 1
VERTEX_SE3:QUAT 3 6 0 0 0 0 0 1
EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
EDGE_SE3:QUAT 2 3 1.1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
G2O
check solve_g2o_disconnected 1 "disconnected.g2o: pose graph: 2 vertices in 1 disconnected part(s) are not linked to a fixed vertex (e.g. vertex 2)" -- "$CARAT" solve-g2o "$scratch/disconnected.g2o" --out "$scratch/never_g2o.g2o"
if [[ -e "$scratch/never_g2o.g2o" ]]; then echo "FAIL solve-g2o left an output after an error"; fail=$((fail + 1)); else pass=$((pass + 1)); fi

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
check map_synthetic 0 "" -- "$CARAT" map --frames "$scratch/seq" --poses "$scratch/seq/poses.txt" --perturb-m 0.1 --perturb-deg 1 --out "$scratch/map_out.txt" --json
cp "$scratch/out" "$scratch/map.json"
if [[ $(json_field "$scratch/map.json" "j['ate_rmse'] < 0.25 * j['initial_ate_rmse'] and j['frames'] == 20") != "True" ]]; then
  echo "FAIL map on the simulated drive: $(head -c 400 "$scratch/map.json")"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
if [[ $(grep -c . "$scratch/map_out.txt") -ne 20 ]]; then echo "FAIL map --out"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
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

# simulate-bal: a BAL problem and its truth, exact counts, the same bytes for the same seed.
check simulate_bal 0 "" -- "$CARAT" simulate-bal --layout ring --cameras 8 --points 50 --observations-per-point 3 --out "$scratch/bal.txt" --truth "$scratch/bal_truth.txt"
if [[ "$(head -1 "$scratch/bal.txt")" != "8 50 150" || $(wc -l <"$scratch/bal.txt") -ne $((1 + 150 + 72 + 150)) || "$(head -1 "$scratch/bal_truth.txt")" != "8 50 150" ]]; then
  echo "FAIL simulate-bal: header '$(head -1 "$scratch/bal.txt")', $(wc -l <"$scratch/bal.txt") lines"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
grep -q "ring scene: 8 cameras, 50 points, 150 observations (0 outliers), seed 1" "$scratch/out" || { echo "FAIL simulate-bal report: $(head -c 300 "$scratch/out")"; fail=$((fail + 1)); }
check simulate_bal_json 0 "" -- "$CARAT" simulate-bal --layout street --cameras 10 --points 200 --observations-per-point 4 --noise 0.5 --outliers 0.1 --seed 9 --out "$scratch/bal_street.txt" --json
expect simulate_bal_json_fields "$(json_field "$scratch/out" "j['layout'] == 'street' and j['cameras'] == 10 and j['points'] == 200 and j['observations'] == 800 and j['outliers'] == 80 and j['seed'] == 9 and j['initial_cost'] > j['truth_cost'] > 0 and 'truth' not in j")"
"$CARAT" simulate-bal --layout street --cameras 10 --points 200 --observations-per-point 4 --noise 0.5 --outliers 0.1 --seed 9 --out "$scratch/bal_street2.txt" >/dev/null
"$CARAT" simulate-bal --layout street --cameras 10 --points 200 --observations-per-point 4 --noise 0.5 --outliers 0.1 --seed 10 --out "$scratch/bal_street3.txt" >/dev/null
if cmp -s "$scratch/bal_street.txt" "$scratch/bal_street2.txt" && ! cmp -s "$scratch/bal_street.txt" "$scratch/bal_street3.txt"; then pass=$((pass + 1)); else
  echo "FAIL simulate-bal: the same seed must give the same file, another seed another"; fail=$((fail + 1)); fi
check simulate_bal_random 0 "" -- "$CARAT" simulate-bal --layout random --cameras 500 --points 1000 --observations-per-point 3 --out "$scratch/bal_random.txt" --json
expect simulate_bal_random_counts "$(json_field "$scratch/out" "j['cameras'] == 500 and j['observations'] == 3000")"
check simulate_bal_bad_layout 2 "--layout" -- "$CARAT" simulate-bal --layout circle --out "$scratch/never.bal"
check simulate_bal_one_camera 2 "--cameras" -- "$CARAT" simulate-bal --cameras 1 --out "$scratch/never.bal"
check simulate_bal_few_points 2 "--points 10 must be at least --cameras 16 (every camera observes a point)" -- "$CARAT" simulate-bal --points 10 --out "$scratch/never.bal"
check simulate_bal_too_many_per_point 2 "--observations-per-point 17 must be at most --cameras 16" -- "$CARAT" simulate-bal --observations-per-point 17 --out "$scratch/never.bal"
check simulate_bal_outliers 2 "--outliers" -- "$CARAT" simulate-bal --outliers 1.5 --out "$scratch/never.bal"
check simulate_bal_noise_nan 2 "--noise" -- "$CARAT" simulate-bal --noise nan --out "$scratch/never.bal"
check simulate_bal_no_out 2 "--out" -- "$CARAT" simulate-bal --cameras 4
check simulate_bal_same_files 2 "--truth and --out name the same file" -- "$CARAT" simulate-bal --out "$scratch/never.bal" --truth "$scratch/never.bal"
check simulate_bal_out_dir 2 "--out" -- "$CARAT" simulate-bal --out "$scratch"
[[ ! -e "$scratch/never.bal" ]] && pass=$((pass + 1)) || { echo "FAIL simulate-bal wrote an output on a usage error"; fail=$((fail + 1)); }

# solve-bal: the Schur complement and the whole system reach the same optimum, near the noise
# floor; the solved problem written with --out reads back at that cost.
"$CARAT" simulate-bal --layout ring --cameras 12 --points 400 --observations-per-point 4 --seed 5 --out "$scratch/ba.bal" --json >"$scratch/ba_sim.json"
check solve_bal_schur 0 "" -- "$CARAT" solve-bal "$scratch/ba.bal" --json --out "$scratch/ba_solved.bal"
cp "$scratch/out" "$scratch/ba_schur.json"
expect solve_bal_schur_fields "$(json_field "$scratch/ba_schur.json" "j['cameras'] == 12 and j['points'] == 400 and j['observations'] == 1600 and j['termination'] == 'CONVERGENCE' and 'schur complement of 400 eliminated' in j['linear_solver'] and j['trust_region_growth'] == 3 and j['final_cost'] < 0.02 * j['initial_cost'] and {'read_s', 'build_s', 'write_s', 'schur_s', 'linearize_s', 'assembly_s'} <= set(j['time_breakdown']) and j['time_s'] >= j['solve_time_s']")"
expect solve_bal_noise_floor "$(python3 -c "import json,sys; a=json.load(open(sys.argv[1])); s=json.load(open(sys.argv[2])); print(0.8 * (s['truth_cost'] - 0.5 * (12 * 9 + 400 * 3)) < a['final_cost'] <= s['truth_cost'])" "$scratch/ba_schur.json" "$scratch/ba_sim.json")"
check solve_bal_cholesky 0 "" -- "$CARAT" solve-bal "$scratch/ba.bal" --json --linear-solver cholesky
expect solve_bal_same_optimum "$(python3 -c "import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); print('schur' not in b['linear_solver'] and abs(a['final_cost'] - b['final_cost']) <= 1e-6 * b['final_cost'])" "$scratch/ba_schur.json" "$scratch/out")"
check solve_bal_resolve 0 "" -- "$CARAT" solve-bal "$scratch/ba_solved.bal" --json --max-iterations 0
expect solve_bal_written_cost "$(python3 -c "import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); print(abs(a['final_cost'] - b['initial_cost']) <= 1e-12 * a['final_cost'])" "$scratch/ba_schur.json" "$scratch/out")"
check solve_bal_report 0 "" -- "$CARAT" solve-bal "$scratch/ba.bal" --threads 2 --loss huber --loss-scale 2
grep -q "^$scratch/ba.bal: 12 cameras, 400 points, 1600 observations$" "$scratch/out" && pass=$((pass + 1)) || { echo "FAIL solve-bal report heading: $(head -c 200 "$scratch/out")"; fail=$((fail + 1)); }
printf '2 2 3\n0 0 1 1\n1 0 2 2\n0 1 3 3\n' >"$scratch/bad.bal"
check solve_bal_truncated 1 "bad.bal:" -- "$CARAT" solve-bal "$scratch/bad.bal"
check solve_bal_bad_solver 2 "--linear-solver" -- "$CARAT" solve-bal "$scratch/ba.bal" --linear-solver qr
check solve_bal_bad_growth 2 "--trust-region-growth" -- "$CARAT" solve-bal "$scratch/ba.bal" --trust-region-growth 0.5
check solve_bal_scale_without_loss 2 "--loss-scale" -- "$CARAT" solve-bal "$scratch/ba.bal" --loss-scale 2
check solve_bal_out_is_input 2 "--out" -- "$CARAT" solve-bal "$scratch/ba.bal" --out "$scratch/ba.bal"
check solve_bal_missing 1 "no-such.bal" -- "$CARAT" solve-bal "$scratch/no-such.bal"
if [[ -f "${CARAT_DATA_DIR:-}/posegraph/dubrovnik-3-7-pre.txt" ]]; then
  check solve_bal_dubrovnik 0 "" -- "$CARAT" solve-bal "$CARAT_DATA_DIR/posegraph/dubrovnik-3-7-pre.txt" --json
  expect solve_bal_dubrovnik_fields "$(json_field "$scratch/out" "j['cameras'] == 3 and j['points'] == 7 and j['observations'] == 19 and j['final_cost'] < j['initial_cost'] and j['termination'] != 'FAILURE'")"
fi
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

# paper --quick: the report, the figures and the JSON numbers the issue asks for.
paper_data=()
if [[ -d "${CARAT_DATA_DIR:-}" ]]; then paper_data=(--data "$CARAT_DATA_DIR"); fi
check paper_quick 0 "" -- "$CARAT" paper --quick --json --out "$scratch/paper" "${paper_data[@]}"
cp "$scratch/out" "$scratch/paper.json"
for f in report.md paper.json fig7_time_breakdown.svg; do
  if [[ ! -s "$scratch/paper/$f" ]]; then echo "FAIL paper did not write $f"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
done
paper_ok=$(json_field "$scratch/paper.json" "all(r['max_relative_error'] < 1e-12 for r in j['table1']['rows']) and [r['M'] for r in j['table1']['rows']] == [29,64,128,256,512,1024] and j['synthetic']['table4'][1]['memory_change_percent'] < -95 and j['synthetic']['table4'][4]['method'] == 'gre_lossless' and abs(j['synthetic']['table4'][4]['ate_change_percent']) < 1e-6")
if [[ $paper_ok != "True" ]]; then echo "FAIL paper tables I/V"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
if [[ -f "${CARAT_DATA_DIR:-}/kitti00_pair/000000.bin" ]]; then
  paper_real=$(json_field "$scratch/paper.json" "all(r['nkld'] <= 1e-10 for r in j['table2']['rows'] if r['sampling'] == 'exact') and [r['nkld'] for r in j['table2']['rows'] if r['sampling'] == 'random'] == sorted([r['nkld'] for r in j['table2']['rows'] if r['sampling'] == 'random'], reverse=True)")
  if [[ $paper_real != "True" ]]; then echo "FAIL paper table II"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
  if ! grep -q "<svg" "$scratch/paper/fig4_displacement_error.svg" 2>/dev/null; then
    echo "FAIL paper did not write fig4_displacement_error.svg"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
  paper_real_data=1
else
  paper_real_data=0
fi
# The paper columns equal the published values, the figures parse as SVG with their series, and
# the JSON keys are documented.
while read -r verdict name; do
  if [[ $verdict == PASS ]]; then pass=$((pass + 1)); else echo "FAIL paper $name"; fail=$((fail + 1)); fi
done < <(python3 "$(dirname "$0")/paper_report_check.py" "$scratch/paper" "$scratch/paper.json" \
           "$(dirname "$0")/../docs/cli.md" "$paper_real_data" 2>&1 || true)

echo "$pass passed, $fail failed"
[[ $fail -eq 0 ]]
