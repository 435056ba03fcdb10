#!/usr/bin/env bash
# End-to-end checks of the carat CLI: simulate-bal, solve-bal and paper --quick.
# Needs CARAT (the binary); uses CARAT_DATA_DIR for real data when present.
source "$(dirname "$0")/cli_common.sh"

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
# --camera-steps parameters: Euclidean cameras, the same optimum.
check solve_bal_camera_parameters 0 "" -- "$CARAT" solve-bal "$scratch/ba.bal" --json --camera-steps parameters
expect solve_bal_camera_parameters_optimum "$(python3 -c "import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); print(a['camera_steps'] == 'centre' and b['camera_steps'] == 'parameters' and abs(a['final_cost'] - b['final_cost']) <= 1e-6 * b['final_cost'])" "$scratch/ba_schur.json" "$scratch/out")"
check solve_bal_bad_camera_steps 2 "--camera-steps" -- "$CARAT" solve-bal "$scratch/ba.bal" --camera-steps world
check solve_bal_resolve 0 "" -- "$CARAT" solve-bal "$scratch/ba_solved.bal" --json --max-iterations 0
expect solve_bal_written_cost "$(python3 -c "import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); print(abs(a['final_cost'] - b['initial_cost']) <= 1e-12 * a['final_cost'])" "$scratch/ba_schur.json" "$scratch/out")"
check solve_bal_report 0 "" -- "$CARAT" solve-bal "$scratch/ba.bal" --threads 2 --loss huber --loss-scale 2
grep -q "^$scratch/ba.bal: 12 cameras, 400 points, 1600 observations$" "$scratch/out" && pass=$((pass + 1)) || { echo "FAIL solve-bal report heading: $(head -c 200 "$scratch/out")"; fail=$((fail + 1)); }
printf '2 2 3\n0 0 1 1\n1 0 2 2\n0 1 3 3\n' >"$scratch/bad.bal"
# --covariance: every camera's 9 x 9 covariance; the scene's similarity (7 free directions) is
# removed by the pseudo-inverse, or is an error when asked for.
check solve_bal_covariance 0 "" -- "$CARAT" solve-bal "$scratch/ba.bal" --json --covariance "$scratch/ba_cov.txt"
expect solve_bal_covariance_json "$(json_field "$scratch/out" "j['covariance_gauge_dimension'] == 7 and j['covariance_s'] >= 0")"
expect solve_bal_covariance_file "$(covariance_file_ok "$scratch/ba_cov.txt" 9 0 1 2 3 4 5 6 7 8 9 10 11)"
check solve_bal_covariance_gauge_error 1 "ba.bal: covariance: H is singular: 7 free directions" -- "$CARAT" solve-bal "$scratch/ba.bal" --covariance "$scratch/never_cov.txt" --covariance-gauge error
[[ ! -e "$scratch/never_cov.txt" ]] && pass=$((pass + 1)) || { echo "FAIL solve-bal wrote --covariance on an error"; fail=$((fail + 1)); }
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

# paper --quick: the report, the figures and the JSON numbers the issue asks for.
paper_data=()
if [[ -d "${CARAT_DATA_DIR:-}" ]]; then paper_data=(--data "$CARAT_DATA_DIR"); fi
# --full-size on a 40-frame drive, its factors' memory capped between M = 256's and M = 1024's.
check paper_quick 0 "" -- "$CARAT" paper --quick --json --out "$scratch/paper" "${paper_data[@]}" \
  --full-size --full-size-frames 40 --full-size-memory 0.01
cp "$scratch/out" "$scratch/paper.json"
expect paper_full_size "$(json_field "$scratch/paper.json" "j['full_size']['ran'] and j['full_size']['frames'] == 40 and [r['solved'] for r in j['full_size']['table4']] == [True, True, False, True, False] and 'over the limit' in j['full_size']['table4'][2]['why_not_solved']")"
check paper_full_size_needs_flag 2 "usage error: --full-size-frames requires --full-size" -- \
  "$CARAT" paper --quick --full-size-frames 40 --out "$scratch/paper_refused"
check paper_full_size_memory_needs_flag 2 "usage error: --full-size-memory requires --full-size" -- \
  "$CARAT" paper --quick --full-size-memory 1 --out "$scratch/paper_refused"
expect paper_full_size_refused_no_output "$([[ ! -e "$scratch/paper_refused" ]] && echo True)"
# Without --full-size: no such section, {"ran": false} (real data left out: an empty --data).
mkdir -p "$scratch/no_data"
check paper_quick_plain 0 "" -- "$CARAT" paper --quick --json --out "$scratch/paper_plain" --data "$scratch/no_data"
expect paper_quick_plain_no_full_size "$(json_field "$scratch/out" "j['full_size'] == {'ran': False}")"
if grep -q "paper's size" "$scratch/paper_plain/report.md"; then echo "FAIL paper_quick_plain report has the full-size section"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
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
