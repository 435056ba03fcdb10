#!/usr/bin/env bash
# carat map under mpirun: 2, 3 and 4 ranks give the poses of one process bit for bit (the --out
# files, the covariances and the JSON ATE; with loop closure shared over 3 ranks too), and a rank
# that sees other files than rank 0, a rank that fails (a frame it cannot read; in the middle of
# the solve) or dies, rank 0 failing (a frame; its linear system over --max-system-memory), and
# sampling the ranks cannot share end the whole run cleanly: one line naming the rank and the
# cause, exit non-zero, no --out, no hang. Other subcommands run on rank 0 alone, usage errors
# print once, and a signal to mpirun leaves no temporary. Skips (exit 77) when carat was built
# without MPI or mpirun is missing. Needs CARAT (the binary) and CARAT_WITH_MPI (ON or OFF).
source "$(dirname "$0")/cli_common.sh"

if [[ "${CARAT_WITH_MPI:-OFF}" != "ON" ]] || ! command -v mpirun >/dev/null; then
  echo "SKIP: carat was built without MPI (or mpirun is missing)"
  exit 77
fi
# OpenMPI refuses to start as root unless asked twice (containers and CI run as root).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpi() {  # mpi NP ARGS...: carat on NP ranks, quiet, never more than 5 minutes
  local np=$1
  shift
  timeout 300 mpirun -q --oversubscribe -np "$np" "$CARAT" "$@"
}

check simulate 0 "" -- "$CARAT" simulate --out "$scratch/seq" --frames 20 --laps 1
cd "$scratch" || exit 1
args=(map --frames seq --poses seq/poses.txt --perturb-m 0.3 --perturb-deg 1 --threads 1 --json)

# Exact (several correspondence rounds) on 1 and 2 ranks; lossless on 1 and 3 ranks.
check map_exact_1 0 "" -- "$CARAT" "${args[@]}" --out exact_1.txt --covariance exact_1.cov
cp out exact_1.json
check map_exact_2 0 "" -- mpi 2 "${args[@]}" --out exact_2.txt --covariance exact_2.cov
cp out exact_2.json
expect exact_2_same_covariances "$(cmp -s exact_1.cov exact_2.cov && echo True)"
check map_exact_4 0 "" -- mpi 4 "${args[@]}" --out exact_4.txt
expect exact_4_same_poses "$(cmp -s exact_1.txt exact_4.txt && echo True)"
# Rank 0 only solving: the two other ranks hold every factor; the same poses.
check map_exact_3_solver_only 0 "" -- mpi 3 "${args[@]}" --mpi-solver-only --out exact_3s.txt
expect exact_3_solver_only_same_poses "$(cmp -s exact_1.txt exact_3s.txt && echo True)"
expect exact_3_solver_only_holds_none "$(python3 -c "
import json, sys
m = json.load(open(sys.argv[1]))['mpi']
h = m['factors_held_per_rank']
print(h[0] == 0 and min(h[1:]) > 0 and m['build_s_per_rank'][0] < min(m['build_s_per_rank'][1:]))" out)"
check solver_only_outside_mpirun 2 "--mpi-solver-only does not apply outside mpirun" -- \
  "$CARAT" "${args[@]}" --mpi-solver-only
# Frames read on demand under a cap, on every rank: still the same poses.
check map_exact_2_capped 0 "" -- mpi 2 "${args[@]}" --max-frame-memory 20 --out exact_2_capped.txt
expect exact_2_capped_same_poses "$(cmp -s exact_1.txt exact_2_capped.txt && echo True)"
check map_lossless_1 0 "" -- "$CARAT" "${args[@]}" --sampling lossless --out lossless_1.txt
cp out lossless_1.json
check map_lossless_3 0 "" -- mpi 3 "${args[@]}" --sampling lossless --out lossless_3.txt
cp out lossless_3.json
# Without a cap no rank reads anything twice: a frame's points at most once (overlap tests) and
# the frame itself at most once (factors).
for pair in exact_1:exact_2 lossless_1:lossless_3; do
  a=${pair%:*} b=${pair#*:}
  expect "${b}_same_poses" "$(cmp -s "$a.txt" "$b.txt" && echo True)"
  expect "${b}_same_ate" "$(python3 -c "
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
ranks = int(sys.argv[3])
m = b['mpi']
print(a['ate_rmse'] == b['ate_rmse'] and a['iterations'] == b['iterations']
      and 'mpi' not in a and m['ranks'] == ranks and m['bytes_gathered'] > 0
      and sum(m['factors_per_rank']) == b['factors'] and len(m['factors_per_rank']) == ranks
      and m['rounds'] >= 1 and len(m['build_s_per_rank']) == ranks
      and len(m['frames_read_per_rank']) == ranks
      and all(0 < n <= b['frames'] for n in m['frames_read_per_rank'])
      and len(m['point_reads_per_rank']) == ranks
      and all(0 < n <= b['frames'] for n in m['point_reads_per_rank'])
      and len(m['pairs_measured_per_rank']) == ranks and len(m['overlap_s_per_rank']) == ranks
      and all(n > 0 for n in m['pairs_measured_per_rank'])
      and len(m['peak_rss_bytes_per_rank']) == ranks and min(m['peak_rss_bytes_per_rank']) > 0
      and m['peak_rss_bytes_per_rank'][0] >= b['peak_rss_bytes']
      and sum(m['bytes_sent_per_rank'][1:]) > m['bytes_gathered']
      and m['factors_held_per_rank'] == m['factors_per_rank'] and m['linearizations'] >= 2
      and m['cost_evaluations'] >= 1
      and m['bytes_per_linearization'] > 728 * sum(m['factors_per_rank'][1:])
      and m['bytes_per_cost_evaluation'] > 8 * sum(m['factors_per_rank'][1:])
      and m['pose_bytes_per_linearization'] == 56 * b['frames']
      and min(m['bytes_sent_per_rank']) > 0 and b['frame_store']['max_bytes'] is None
      and 'frame_store' not in a)" "$a.json" "$b.json" "${b##*_}")"
done

# Loop closure over the ranks: each describes a stretch of the frames, validates a stretch of the
# candidates and registers a stretch of the consecutive pairs; the loops, their pose graph and the
# map are one process's.
check simulate_loop 0 "" -- "$CARAT" simulate --out "$scratch/loop" --frames 32 --laps 2
loop_args=(map --frames loop --poses loop/poses.txt --perturb-m 0.3 --perturb-deg 1 --threads 1
  --loops --json)
check loops_1 0 "" -- "$CARAT" "${loop_args[@]}" --out loops_1.txt
cp out loops_1.json
check loops_3 0 "" -- mpi 3 "${loop_args[@]}" --out loops_3.txt
cp out loops_3.json
expect loops_3_same_poses "$(cmp -s loops_1.txt loops_3.txt && echo True)"
expect loops_3_same_loops "$(python3 -c "
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
m = b['mpi']
print(a['loops'] == {**b['loops'], 'time_s': a['loops']['time_s'], 'pgo': {**b['loops']['pgo'],
      'time_s': a['loops']['pgo']['time_s']}} and a['loops']['accepted'] > 5
      and len(m['loop_pairs_per_rank']) == 3 and min(m['loop_pairs_per_rank']) > 0
      and sum(m['loop_pairs_per_rank']) == a['loops']['candidates'] + 2 * a['frames'] - 1
      and len(m['loop_s_per_rank']) == 3)" loops_1.json loops_3.json)"

# A rank that sees other files: each rank runs in its own folder, as if the shared filesystem
# served rank 1 a truncated copy of frame 3 (rank 0 sends every file's size; a rank checks them
# before reading any frame).
mkdir -p good bad/seq nan/seq
ln -s ../seq good/seq
cp seq/* bad/seq/
head -c 100 seq/000003.bin >bad/seq/000003.bin
check rank_other_files 1 "carat: error: rank 1 of 2: seq/000003.bin: 100 bytes on this rank but" -- \
  timeout 300 mpirun -q --oversubscribe -np 1 --wdir "$scratch/good" "$CARAT" "${args[@]}" --out out.txt : \
  -np 1 --wdir "$scratch/bad" "$CARAT" "${args[@]}" --out out.txt
expect rank_other_files_no_out "$([[ ! -e good/out.txt && ! -e bad/out.txt ]] && echo True)"
# A rank that cannot read a frame of the right size (NaN coordinates), found in its share of the
# dense graph's candidate pairs (frame 3 among them).
cp seq/* nan/seq/
python3 -c "import sys; open(sys.argv[1], 'r+b').write(b'\xff' * 64)" nan/seq/000003.bin
check rank_fails 1 "carat: error: rank 1 of 2: seq/000003.bin: point 0 is not finite" -- \
  timeout 300 mpirun -q --oversubscribe -np 1 --wdir "$scratch/good" "$CARAT" "${args[@]}" --out out.txt : \
  -np 1 --wdir "$scratch/nan" "$CARAT" "${args[@]}" --out out.txt
expect rank_fails_no_out "$([[ ! -e good/out.txt && ! -e nan/out.txt ]] && echo True)"
# A rank fails in the middle of the solve (its 2nd linearization), or dies there: one line naming
# the rank, exit non-zero, no --out, no hang.
check rank_fails_solving 1 "carat: error: rank 1 of 2: failed as CARAT_MPI_TEST_FAULT asked, in linearization 2" -- \
  timeout 300 mpirun -q --oversubscribe -np 1 "$CARAT" "${args[@]}" --out solving.txt : \
  -np 1 env CARAT_MPI_TEST_FAULT=throw@2 "$CARAT" "${args[@]}" --out solving.txt
expect rank_fails_solving_no_out "$([[ ! -e solving.txt ]] && echo True)"
timeout 300 mpirun -q --oversubscribe -np 1 "$CARAT" "${args[@]}" --out dies.txt : \
  -np 1 env CARAT_MPI_TEST_FAULT=abort@2 "$CARAT" "${args[@]}" --out dies.txt >dies.out 2>&1
status=$?
expect rank_dies_solving_ends_the_job "$([[ $status -ne 0 && $status -ne 124 && ! -e dies.txt ]] && echo True)"
# Rank 0 fails (in its share of the dense graph): the others are told to stop.
check rank0_fails 1 "carat: error: rank 0 of 2: seq/000003.bin: 100 bytes is not a whole number" -- \
  timeout 300 mpirun -q --oversubscribe -np 1 --wdir "$scratch/bad" "$CARAT" "${args[@]}" --out out.txt : \
  -np 1 --wdir "$scratch/good" "$CARAT" "${args[@]}" --out out.txt
expect rank0_fails_no_out "$([[ ! -e good/out.txt && ! -e bad/out.txt ]] && echo True)"
# Rank 0's reduced system over --max-system-memory: one message naming rank 0 and the estimate.
check rank0_system_over_cap 1 "carat: error: rank 0 of 2: global registration: the solve failed: linear solver: sparse Cholesky of the whole system needs about" -- \
  mpi 2 "${args[@]}" --max-system-memory 0.001 --out capped.txt
expect rank0_system_over_cap_no_out "$([[ ! -e capped.txt ]] && echo True)"
# What the ranks cannot share.
check mpi_full 2 "--sampling full runs in one process; under mpirun use --sampling exact or lossless" -- \
  mpi 2 "${args[@]}" --sampling full
check mpi_random 2 "--sampling random runs in one process" -- mpi 2 "${args[@]}" --sampling random
check mpi_pgo 2 "--method pgo runs in one process" -- mpi 2 "${args[@]}" --method pgo

# Every other subcommand runs on rank 0 alone (one report, one writer), and only rank 0 prints a
# usage error (one line, whichever subcommand).
check mpi_solve_g2o 0 "" -- mpi 2 solve-g2o tiny.g2o --out tiny_solved.g2o
expect mpi_solve_g2o_once "$([[ $(grep -c '^wrote tiny_solved.g2o' out) -eq 1 && $(grep -c '^VERTEX_SE3:QUAT' tiny_solved.g2o) -eq 3 ]] && echo True)"
check mpi_usage_error_once 2 "carat: usage error: The following argument was not expected: --bogus" -- mpi 3 solve-g2o tiny.g2o --bogus
check mpi_map_usage_error_once 2 "--bogus" -- mpi 2 "${args[@]}" --bogus
# SIGTERM or SIGINT to mpirun at any moment: rank 0's hidden temporary beside --out never stays
# (mpirun kills every rank with SIGKILL as soon as one has ended by a signal).
mkdir -p signalled
left=""
for k in $(seq 1 12); do
  sig=TERM; (( k % 2 )) || sig=INT
  mpirun -q --oversubscribe -np 2 "$CARAT" "${args[@]}" --out signalled/out.txt >/dev/null 2>&1 &
  launcher=$!
  sleep "0.$(( (k * 7) % 10 ))"
  kill -"$sig" "$launcher"
  wait "$launcher"
  left+=$(ls -A signalled | grep '\.tmp-')
done
expect mpi_signal_no_temporary "$([[ -z "$left" ]] && echo True)"

echo "cli_mpi: $pass passed, $fail failed"
[[ $fail -eq 0 ]]
