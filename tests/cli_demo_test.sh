#!/usr/bin/env bash
# End-to-end checks of `carat demo`: the report, the JSON fields, the written files, the drifting
# start with its loops, and progress bars on a terminal only.
# Needs CARAT (the binary).
source "$(dirname "$0")/cli_common.sh"

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
# Progress bars: drawn on a terminal (a pseudo-terminal from util-linux's script), never in a pipe
# (a 400-frame simulation on one thread: its one stage runs for about three times the second a
# bar waits).
if command -v script >/dev/null; then
  script -qec "'$CARAT' simulate --frames 400 --threads 1 --out '$scratch/sim-tty'" /dev/null >"$scratch/tty.log" 2>&1 || true
  if ! grep -q "simulating frames *\[#" "$scratch/tty.log"; then
    echo "FAIL simulate on a terminal drew no progress bar"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
  "$CARAT" simulate --frames 400 --threads 1 --out "$scratch/sim-pipe" >/dev/null 2>"$scratch/pipe.log"
  if grep -q "\[#" "$scratch/pipe.log"; then echo "FAIL progress bar drawn into a file"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
fi
# GRE lossless: the full factors' optimum (same ATE to 1e-9 relative) in < 0.5 % of their memory.
demo_lossless=$(json_field "$scratch/demo.json" "(lambda m: abs(m['gre_lossless']['ate_rmse'] - m['gre_full']['ate_rmse']) <= 1e-9 * m['gre_full']['ate_rmse'] and m['gre_lossless']['memory_bytes'] * 200 < m['gre_full']['memory_bytes'] and m['gre_lossless']['iterations'] == m['gre_full']['iterations'])({m['method']: m for m in j['methods']})")
if [[ $demo_lossless != "True" ]]; then echo "FAIL demo: GRE lossless is not the full optimum in < 0.5 % of the memory"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
for f in ground_truth_kitti.txt ground_truth_tum.txt initial_kitti.txt gre_exact_kitti.txt gre_exact_tum.txt pgo_hessian_tum.txt trajectories_before.svg trajectories_after.svg frame_errors.svg graph.svg demo.json; do
  if [[ ! -s "$scratch/demo/$f" ]]; then echo "FAIL demo did not write $f"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
done
if [[ $(grep -c . "$scratch/demo/gre_exact_kitti.txt") -ne 24 ]]; then echo "FAIL demo trajectory has the wrong length"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
grep -q "<svg" "$scratch/demo/graph.svg" && grep -q "<line" "$scratch/demo/graph.svg" || { echo "FAIL graph.svg has no edges"; fail=$((fail + 1)); }
# The per-frame error plot: one line per method and one for the initial guess.
if [[ $(grep -c "<polyline" "$scratch/demo/frame_errors.svg") -ne 7 ]]; then echo "FAIL frame_errors.svg does not hold 7 lines"; fail=$((fail + 1)); else pass=$((pass + 1)); fi

echo "$pass passed, $fail failed"
[[ $fail -eq 0 ]]
