#!/usr/bin/env bash
# End-to-end checks of the carat CLI: outputs, exit codes, one-line errors, no partial files.
# Needs CARAT (the binary); uses CARAT_DATA_DIR for real data when present.
source "$(dirname "$0")/cli_common.sh"

# --version: the version of CMakeLists.txt's project(VERSION).
project_version=$(sed -n 's/^project(carat VERSION \([0-9.]*\).*/\1/p' "$(dirname "$0")/../CMakeLists.txt")
check version 0 "" -- "$CARAT" --version
if [[ -z $project_version || "$(head -n 1 "$scratch/out")" != "carat $project_version" ]]; then
  echo "FAIL --version printed '$(cat "$scratch/out")', expected 'carat $project_version'"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
# Its second line names OpenBLAS's kernels; on a CPU with AVX2 and FMA never the Prescott fallback
# (carat restarts itself with OPENBLAS_CORETYPE set), unless the user set OPENBLAS_CORETYPE.
blas_line=$(sed -n 2p "$scratch/out")
if [[ $blas_line == "BLAS: OpenBLAS, kernels "* && -z ${OPENBLAS_CORETYPE+x} ]] &&
   grep -qw avx2 /proc/cpuinfo && grep -qw fma /proc/cpuinfo &&
   [[ ${blas_line,,} == *prescott ]]; then
  echo "FAIL --version: OpenBLAS runs its Prescott fallback on an AVX2 CPU: '$blas_line'"
  fail=$((fail + 1))
else pass=$((pass + 1)); fi
OPENBLAS_CORETYPE=Prescott "$CARAT" --version >"$scratch/out" 2>&1
if [[ $(sed -n 2p "$scratch/out") == "BLAS: OpenBLAS, kernels "* &&
      $(sed -n 2p "$scratch/out") != "BLAS: OpenBLAS, kernels Prescott" ]]; then
  echo "FAIL --version: OPENBLAS_CORETYPE=Prescott was not left as set: '$(cat "$scratch/out")'"
  fail=$((fail + 1))
else pass=$((pass + 1)); fi

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

# --covariance: one line per free vertex (not vertex 0, held constant), its g2o id and its 6 x 6
# covariance; written with the graph, never over it or the input.
check solve_g2o_covariance 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --json --covariance "$scratch/cov.txt"
expect solve_g2o_covariance_json "$(json_field "$scratch/out" "j['covariance'] == '$scratch/cov.txt' and j['covariance_s'] >= 0")"
expect solve_g2o_covariance_file "$(covariance_file_ok "$scratch/cov.txt" 6 1 2)"
check solve_g2o_covariance_is_out 2 "--covariance $scratch/same.txt is the same file as --out $scratch/same.txt" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out "$scratch/same.txt" --covariance "$scratch/same.txt"
check solve_g2o_covariance_is_input 2 "--covariance $scratch/tiny.g2o is the same file as the input FILE" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --covariance "$scratch/tiny.g2o"
check solve_g2o_gauge_alone 2 "--covariance-gauge does not apply without --covariance" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --covariance-gauge pseudo-inverse
[[ ! -e "$scratch/same.txt" ]] && pass=$((pass + 1)) || { echo "FAIL solve-g2o wrote an output on a usage error"; fail=$((fail + 1)); }

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
check solve_g2o_2d 0 "" -- "$CARAT" solve-g2o "$scratch/square2d.g2o" --json --out "$scratch/square2d_solved.g2o" --covariance "$scratch/square2d_cov.txt"
cp "$scratch/out" "$scratch/square2d.json"
if [[ $(json_field "$scratch/square2d.json" "j['dimension'] == 2 and j['vertices'] == 4 and j['edges'] == 4 and j['final_cost'] < 1e-12 < j['initial_cost']") != "True" ]]; then
  echo "FAIL solve-g2o did not solve the 2D square"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
if ! awk '$1 == "VERTEX_SE2" && $2 == 1 { exit !(($3 - 1) ^ 2 < 1e-12 && $4 ^ 2 < 1e-12) }' "$scratch/square2d_solved.g2o"; then
  echo "FAIL --out did not write the solved 2D graph"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
expect solve_g2o_2d_covariance "$(covariance_file_ok "$scratch/square2d_cov.txt" 3 1 2 3)"
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
check bad_anderson_memory 2 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --anderson-memory 65
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


echo "$pass passed, $fail failed"
[[ $fail -eq 0 ]]
