#!/usr/bin/env bash
# The CLI against hostile options, inputs and outputs (docs/reliability.md states the contract):
# NaN / Inf / wrap-around values for every option, header numbers that wrap, special files as
# inputs and outputs, outputs that are inputs, interrupted runs, silent wrong results.
# Needs CARAT (the binary).
source "$(dirname "$0")/cli_common.sh"

# Fixtures (besides the tiny pose graph from cli_common.sh): trajectories, a few points, a short simulated drive.
cat >"$scratch/ref.kitti" <<'KITTI'
1 0 0 0 0 1 0 0 0 0 1 0
0 -1 0 2 1 0 0 1 0 0 1 0.5
1 0 0 4 0 0 -1 -1 0 1 0 1
1 0 0 3 0 1 0 5 0 0 1 -2
KITTI
python3 -c "import struct,sys; open(sys.argv[1],'wb').write(struct.pack('<12f', *[0.0]*12))" "$scratch/few.bin"
"$CARAT" simulate --out "$scratch/seq" --frames 20 --laps 1 >/dev/null || { echo "FAIL simulate fixture"; exit 1; }
"$CARAT" simulate --out "$scratch/seq-long" --frames 12 --laps 1 >/dev/null || { echo "FAIL simulate fixture"; exit 1; }

# ---------------------------------------------------------------------------------------------
# Reliability: hostile options, inputs and outputs (docs/reliability.md states the contract).

# Every floating-point option refuses NaN and infinities (exit 2, naming the option).
seqdir="$scratch/seq"
float_options=(
  "demo --overlap" "demo --max-distance" "demo --pgo-cauchy" "demo --gre-cauchy" "demo --gre-excess-cauchy"
  "solve-g2o $scratch/tiny.g2o --loss-scale" "solve-g2o $scratch/tiny.g2o --trust-region-growth"
  "coreset-check --scale"
  "align --target $scratch/few.bin --source $scratch/few.bin --voxel" "align --target $scratch/few.bin --source $scratch/few.bin --max-distance"
  "ate --estimate $scratch/ref.kitti --reference $scratch/ref.kitti --max-difference"
  "map --frames $seqdir --poses $seqdir/poses.txt --voxel" "map --frames $seqdir --poses $seqdir/poses.txt --overlap"
  "map --frames $seqdir --poses $seqdir/poses.txt --max-distance" "map --frames $seqdir --poses $seqdir/poses.txt --gre-excess-cauchy"
  "map --frames $seqdir --poses $seqdir/poses.txt --perturb-m" "map --frames $seqdir --poses $seqdir/poses.txt --perturb-deg"
  "paper --out $scratch/never-paper --gre-excess-cauchy"
)
for entry in "${float_options[@]}"; do
  read -r -a words <<<"$entry"
  option=${words[${#words[@]} - 1]}
  for value in nan -nan inf -inf 1e999 0x10 ""; do
    check "nan_option_${words[0]}_${option}_${value}" 2 "$option" -- "$CARAT" "${words[@]}" "$value"
  done
done
# Integers: no sign on unsigned values, no wrap-around, no hex, no fractions.
for cmd in "demo --seed" "simulate --out $scratch/never-sim --seed" "paper --out $scratch/never-paper --seed" "coreset-check --seed" "map --frames $seqdir --poses $seqdir/poses.txt --seed"; do
  read -r -a words <<<"$cmd"
  for value in -1 18446744073709551616 1e3 0x10 1.5 nan; do
    check "integer_option_${words[0]}_seed_${value}" 2 "--seed" -- "$CARAT" "${words[@]}" "$value"
  done
done
for value in -1 18446744073709551616 1e3 0x10 1.5 nan; do
  check "integer_option_simulate_bal_seed_${value}" 2 "--seed" -- "$CARAT" simulate-bal --out "$scratch/never.bal" --seed "$value"
done
check simulate_bal_points_fraction 2 "--points" -- "$CARAT" simulate-bal --out "$scratch/never.bal" --points 100.5
check simulate_bal_points_overflow 2 "--points * --observations-per-point is 2200000000 observations; the BAL format holds at most 2147483647" -- "$CARAT" simulate-bal --out "$scratch/never.bal" --points 100000000 --observations-per-point 22 --cameras 22
# A failed simulate-bal leaves an existing output as it was.
echo "keep" >"$scratch/keep.bal"
check simulate_bal_truth_missing_folder 2 "--truth" -- "$CARAT" simulate-bal --out "$scratch/keep.bal" --truth "$scratch/no-such-folder/t.bal"
[[ "$(cat "$scratch/keep.bal")" == "keep" ]] && pass=$((pass + 1)) || { echo "FAIL simulate-bal replaced --out on a usage error"; fail=$((fail + 1)); }
check simulate_bal_out_unwritable 1 "" -- "$CARAT" simulate-bal --out /proc/carat-cannot-write.bal --cameras 4 --points 8
check frames_hex 2 "--frames: must be an integer in [12, 100000], got '0x10'" -- "$CARAT" demo --frames 0x10
check frames_fraction 2 "--frames" -- "$CARAT" simulate --out "$scratch/never-sim" --frames 10.5
check threads_negative 2 "--threads" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --threads -1
check iterations_wrap 2 "--max-iterations" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --max-iterations 4294967296
# Extreme but in-range kernel scales are refused at parsing, never an overflow inside the solve.
check loss_scale_huge 2 "--loss-scale: must be a finite number in [1e-06, 1e+06], got '1e300'" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --loss cauchy --loss-scale 1e300
check loss_scale_tiny 2 "--loss-scale" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --loss cauchy --loss-scale 1e-300
check loss_scale_edge 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --loss cauchy --loss-scale 1e6 --json
check excess_tiny 2 "--gre-excess-cauchy" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --gre-excess-cauchy 1e-300
# Option combinations and machine limits: usage errors that name the options, before any work.
check coreset_dim_clusters 2 "--clusters 64 is too few for --dim 12: at least 93 clusters" -- "$CARAT" coreset-check --dim 12 --target 92 --clusters 64
# The default number of clusters follows the dimension: --dim 12 works without --clusters.
check coreset_dim12_default 0 "" -- "$CARAT" coreset-check --dim 12 --target 92 --rows 5000 --trials 2 --json
expect coreset_dim12_exact "$(json_field "$scratch/out" "j['clusters'] == 184 and j['rows_out_max'] == 92 and max(j['max_rel_error_H'], j['max_rel_error_b'], j['max_rel_error_c']) <= 1e-12")"
check coreset_memory 2 "--rows 100000000 --dim 64 needs about" -- "$CARAT" coreset-check --rows 100000000 --dim 64 --clusters 3000
check simulate_disk 2 "--frames 1000000: the drive would take about" -- "$CARAT" simulate --out "$scratch/never-sim" --frames 1000000
check demo_memory 2 "--frames 100000: the demo holds every frame" -- "$CARAT" demo --frames 100000 --out "$scratch/never-demo"
for d in never-sim never-demo never-paper; do
  [[ -e "$scratch/$d" ]] && { echo "FAIL a refused run created $d"; fail=$((fail + 1)); }
done

# Header numbers that wrap size_t: refused with the file named, never read out of bounds.
mkdir -p "$scratch/pcd_frames"
python3 - "$scratch" <<'PY2'
import struct, sys
d = sys.argv[1]
payload = struct.pack('<6f', 1, 2, 3, 4, 5, 6)
head = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT {}\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA {}\n"
open(d + "/wrap_binary.pcd", "wb").write(head.format("4611686018427387904 1 1", "binary").encode() + payload)
open(d + "/wrap_ascii.pcd", "wb").write(head.format("1 18446744073709551615 1", "ascii").encode() + b"1 2 3\n4 5 6\n")
open(d + "/sum_wraps.pcd", "wb").write(head.format("1 4611686018427387903 4611686018427387903", "binary").encode() + payload)
open(d + "/wrap.ply", "wb").write(b"ply\nformat binary_little_endian 1.0\nelement vertex 4611686018427387904\nproperty float x\nproperty float y\nproperty float z\nend_header\n" + payload)
PY2
check pcd_count_wraps_binary 1 "wrap_binary.pcd: the size of field 'x' overflows" -- "$CARAT" align --target "$scratch/wrap_binary.pcd" --source "$scratch/wrap_binary.pcd"
check pcd_count_wraps_ascii 1 "wrap_ascii.pcd: the size of field 'y' overflows" -- "$CARAT" align --target "$scratch/wrap_ascii.pcd" --source "$scratch/wrap_ascii.pcd"
check pcd_sum_wraps 1 "sum_wraps.pcd: the point record size overflows" -- "$CARAT" align --target "$scratch/sum_wraps.pcd" --source "$scratch/sum_wraps.pcd"
check ply_count_wraps 1 "wrap.ply: announces 4611686018427387904 points" -- "$CARAT" align --target "$scratch/wrap.ply" --source "$scratch/wrap.ply"
cp "$seqdir"/*.bin "$scratch/pcd_frames/"
rm "$scratch/pcd_frames/000003.bin"
cp "$scratch/wrap_binary.pcd" "$scratch/pcd_frames/000003.pcd"
check map_pcd_count_wraps 1 "000003.pcd: the size of field 'x' overflows" -- "$CARAT" map --frames "$scratch/pcd_frames" --poses "$seqdir/poses.txt"

# Inputs that are not regular files or never end: refused or read with a bound, naming the file.
check ate_dev_zero 1 "/dev/zero:1: holds a NUL byte (a binary file?)" -- "$CARAT" ate --estimate /dev/zero --reference "$scratch/ref.kitti"
check ate_reference_dev_zero 1 "/dev/zero:1: holds a NUL byte" -- "$CARAT" ate --estimate "$scratch/ref.kitti" --reference /dev/zero
check g2o_dev_zero 1 "/dev/zero:1: holds a NUL byte" -- "$CARAT" solve-g2o /dev/zero
check g2o_dev_null 1 "/dev/null: no VERTEX_SE3:QUAT records" -- "$CARAT" solve-g2o /dev/null
check map_poses_dev_zero 1 "/dev/zero:1: holds a NUL byte" -- "$CARAT" map --frames "$seqdir" --poses /dev/zero
ln -sf /dev/zero "$scratch/zero.bin"
check align_dev_zero 1 "zero.bin: is a character device, not a regular file" -- "$CARAT" align --target "$scratch/zero.bin" --source "$scratch/zero.bin"
mkfifo "$scratch/fifo.bin"
check align_fifo 1 "fifo.bin: is a FIFO, not a regular file" -- "$CARAT" align --target "$scratch/fifo.bin" --source "$scratch/fifo.bin"
mkdir -p "$scratch/fifo_frames" && cp "$seqdir"/*.bin "$scratch/fifo_frames/" && rm "$scratch/fifo_frames/000005.bin" && mkfifo "$scratch/fifo_frames/000005.bin"
check map_fifo_frame 1 "000005.bin: is not a regular file" -- "$CARAT" map --frames "$scratch/fifo_frames" --poses "$seqdir/poses.txt"
# Text from a pipe is fine (process substitution).
check ate_from_pipe 0 "" -- bash -c "'$CARAT' ate --estimate <(cat '$scratch/ref.kitti') --reference '$scratch/ref.kitti' --json"
# A sparse 20 GB scan is refused from its size, before any allocation.
truncate -s 20G "$scratch/sparse.bin"
check sparse_huge_scan 1 "sparse.bin: holds 1342177280 points, more than the 100000000 carat reads from one file" -- "$CARAT" align --target "$scratch/sparse.bin" --source "$scratch/sparse.bin"
rm -f "$scratch/sparse.bin"
# TUM stamp matching is not n x m: 20,000 poses each with an unbounded stamp difference.
python3 -c "
import sys
with open(sys.argv[1], 'w') as f:
    for k in range(20000): f.write('%d.0 %d 0 0 0 0 0 1\n' % (k, k))" "$scratch/long.tum"
check ate_tum_20k 0 "" -- "$CARAT" ate --estimate "$scratch/long.tum" --reference "$scratch/long.tum" --format tum --max-difference 1e9 --json
expect ate_tum_20k_pairs "$(json_field "$scratch/out" "j['num_poses'] == 20000 and j['rmse'] < 1e-9")"

# Messages never echo raw bytes: control bytes and long garbage become a short quoted token.
printf 'VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n\001\033[31mEVIL\033[0m%s 1 2\n' "$(head -c 1000 /dev/zero | tr '\0' 'x')" >"$scratch/evil.g2o"
check g2o_raw_bytes 1 "evil.g2o:2: unknown record '??[31mEVIL?[0mxxxxxxxxxx" -- "$CARAT" solve-g2o "$scratch/evil.g2o"
if [[ $(wc -c <"$scratch/err") -gt 300 ]] || grep -qP '[\x00-\x08\x0e-\x1f]' "$scratch/err"; then echo "FAIL the g2o error echoes raw bytes"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
mkdir -p "$scratch/far_frames" && cp "$seqdir"/*.bin "$scratch/far_frames/"
python3 -c "import struct,sys; f=open(sys.argv[1],'r+b'); f.seek(16*7); f.write(struct.pack('<f', 3e37))" "$scratch/far_frames/000001.bin"
check map_far_point 1 "000001.bin: point 7 is too far from the origin for 0.25 m voxels" -- "$CARAT" map --frames "$scratch/far_frames" --poses "$seqdir/poses.txt"
awk '{ $4 = 1e300; print }' "$scratch/ref.kitti" >"$scratch/huge.kitti"
check ate_overflow 1 "huge.kitti against $scratch/ref.kitti: the error of pose 0 overflows (coordinates too large)" -- "$CARAT" ate --estimate "$scratch/huge.kitti" --reference "$scratch/ref.kitti" --no-align

# Outputs: regular files replaced atomically keeping their mode; devices and FIFOs written
# through; links followed; an output that is an input refused; long names fit.
cp "$scratch/tiny.g2o" "$scratch/keep.g2o"
check out_equals_input 2 "--out $scratch/keep.g2o is the same file as the input FILE $scratch/keep.g2o" -- "$CARAT" solve-g2o "$scratch/keep.g2o" --out "$scratch/keep.g2o"
ln -sf keep.g2o "$scratch/keep_link.g2o"
check out_link_to_input 2 "is the same file as the input FILE" -- "$CARAT" solve-g2o "$scratch/keep.g2o" --out "$scratch/keep_link.g2o"
cmp -s "$scratch/keep.g2o" "$scratch/tiny.g2o" && pass=$((pass + 1)) || { echo "FAIL solve-g2o touched its input"; fail=$((fail + 1)); }
cp "$seqdir/poses.txt" "$scratch/ref_poses.txt"
check map_out_equals_poses 2 "is the same file as the input --poses" -- "$CARAT" map --frames "$seqdir" --poses "$scratch/ref_poses.txt" --out "$scratch/ref_poses.txt"
check map_out_is_a_frame 2 "is the same file as the input --frames" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --out "$seqdir/000002.bin"
cmp -s "$scratch/ref_poses.txt" "$seqdir/poses.txt" && pass=$((pass + 1)) || { echo "FAIL map touched its reference"; fail=$((fail + 1)); }
check out_dev_null 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out /dev/null
[[ -c /dev/null ]] && pass=$((pass + 1)) || { echo "FAIL /dev/null is no longer a character device"; fail=$((fail + 1)); }
mkfifo "$scratch/out.fifo"
(cat "$scratch/out.fifo" >"$scratch/fifo_received.g2o") &
reader=$!
check out_fifo 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out "$scratch/out.fifo"
wait $reader
[[ -p "$scratch/out.fifo" ]] && grep -q "^VERTEX_SE3:QUAT 2 " "$scratch/fifo_received.g2o" && pass=$((pass + 1)) || { echo "FAIL --out FIFO was replaced or not written through"; fail=$((fail + 1)); }
mkdir -p "$scratch/links" && echo old >"$scratch/links/target.g2o" && chmod 640 "$scratch/links/target.g2o" && ln -sf target.g2o "$scratch/links/link.g2o"
check out_symlink 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out "$scratch/links/link.g2o"
[[ -L "$scratch/links/link.g2o" ]] && grep -q "^VERTEX_SE3:QUAT 2 " "$scratch/links/target.g2o" && [[ $(stat -c %a "$scratch/links/target.g2o") == 640 ]] && [[ $(ls -A "$scratch/links" | wc -l) -eq 2 ]] && pass=$((pass + 1)) || { echo "FAIL --out symlink: link replaced, target not written or mode changed"; fail=$((fail + 1)); }
long_name=$(printf 'n%.0s' $(seq 1 250)).g2o
long_name=${long_name:0:250}
check out_long_name 0 "" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out "$scratch/links/$long_name"
[[ -s "$scratch/links/$long_name" ]] && pass=$((pass + 1)) || { echo "FAIL a 250-character output name"; fail=$((fail + 1)); }
check out_is_directory 2 "is a directory, not a file" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out "$scratch/links"
check out_missing_folder 2 "does not exist" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --out "$scratch/nowhere/x.g2o"
# Folder outputs: a device, a file or a folder carat did not write is refused before any work.
check demo_out_dev_null 2 "--out /dev/null: exists and is not a folder" -- "$CARAT" demo --frames 12 --out /dev/null
check simulate_out_dev_null 2 "--out /dev/null: exists and is not a folder" -- "$CARAT" simulate --frames 3 --out /dev/null
check paper_out_dev_null 2 "--out /dev/null: exists and is not a folder" -- "$CARAT" paper --quick --out /dev/null
[[ -c /dev/null ]] && pass=$((pass + 1)) || { echo "FAIL /dev/null replaced"; fail=$((fail + 1)); }
mkdir -p "$scratch/user_folder" && echo precious >"$scratch/user_folder/notes.txt"
check simulate_user_folder 2 "exists, is not empty and was not written by carat" -- "$CARAT" simulate --frames 3 --out "$scratch/user_folder"
check paper_out_holds_data 2 "holds the input --data" -- "$CARAT" paper --quick --out "$scratch/seq" --data "$scratch/seq"
[[ $(cat "$scratch/user_folder/notes.txt") == precious ]] && pass=$((pass + 1)) || { echo "FAIL a user folder was touched"; fail=$((fail + 1)); }
# An earlier carat output is replaced whole: a shorter drive leaves no stale frames.
check simulate_into_old 0 "" -- "$CARAT" simulate --out "$scratch/seq-long" --frames 5 --laps 1
[[ $(ls "$scratch/seq-long" | grep -c '\.bin$') -eq 5 ]] && [[ -f "$scratch/seq-long/.carat-output" ]] && pass=$((pass + 1)) || { echo "FAIL simulate into an earlier output left stale frames: $(ls "$scratch/seq-long" | wc -l) files"; fail=$((fail + 1)); }
ls -A "$scratch" | grep -q '\.tmp-' && { echo "FAIL a temporary was left behind: $(ls -A "$scratch" | grep '\.tmp-')"; fail=$((fail + 1)); }

# Interrupted runs leave nothing behind and the earlier output untouched.
"$CARAT" simulate --out "$scratch/sig" --frames 3 >/dev/null 2>&1
"$CARAT" simulate --out "$scratch/sig" --frames 1500 >/dev/null 2>&1 &
victim=$!
for _ in $(seq 1 200); do ls -A "$scratch" | grep -q '^\.sig\.tmp-' && break; sleep 0.05; done
sleep 0.5
kill -TERM $victim
wait $victim
rc=$?
if [[ $rc -ne 143 ]] || ls -A "$scratch" | grep -q '^\.sig\.' || [[ $(ls "$scratch/sig" | grep -c '\.bin$') -ne 3 ]]; then
  echo "FAIL SIGTERM during simulate: exit $rc, left $(ls -A "$scratch" | grep '^\.sig' | head -3), $(ls "$scratch/sig" | wc -l) files in the old output"; fail=$((fail + 1))
else pass=$((pass + 1)); fi
"$CARAT" simulate --out "$scratch/sigint" --frames 1500 >/dev/null 2>&1 &
victim=$!
for _ in $(seq 1 200); do ls -A "$scratch" | grep -q '^\.sigint\.tmp-' && break; sleep 0.05; done
kill -INT $victim
wait $victim
rc=$?
if [[ $rc -ne 130 ]] || ls -A "$scratch" | grep -q '^\.sigint' || [[ -e "$scratch/sigint" ]]; then
  echo "FAIL SIGINT during simulate: exit $rc"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
mkfifo "$scratch/slow.g2o"
echo "old output" >"$scratch/sig_out.g2o"
"$CARAT" solve-g2o "$scratch/slow.g2o" --out "$scratch/sig_out.g2o" >/dev/null 2>&1 &
victim=$!
exec 7>"$scratch/slow.g2o"   # a writer that sends half a graph and then stalls: the run is mid-read
head -n 3 "$scratch/tiny.g2o" >&7
sleep 0.3
kill -TERM $victim
wait $victim
rc=$?
exec 7>&-
if [[ $rc -ne 143 ]] || [[ $(cat "$scratch/sig_out.g2o") != "old output" ]] || ls -A "$scratch" | grep -q '^\.sig_out'; then
  echo "FAIL SIGTERM during solve-g2o: exit $rc"; fail=$((fail + 1)); else pass=$((pass + 1)); fi

# Write errors on standard output are errors.
check stdout_full 1 "cannot write the output to standard output: No space left on device" -- bash -c "'$CARAT' ate --estimate '$scratch/ref.kitti' --reference '$scratch/ref.kitti' --json >/dev/full"

# Silent wrong results: graph.txt poses pair with frames by id, not by line.
python3 - "$seqdir/poses.txt" "$scratch" <<'PY2'
import math, random, sys
rows = [list(map(float, l.split())) for l in open(sys.argv[1]) if l.strip()]
def quat(r):
    m = [[r[0], r[1], r[2]], [r[4], r[5], r[6]], [r[8], r[9], r[10]]]
    t = m[0][0] + m[1][1] + m[2][2]
    if t > 0:
        s = math.sqrt(t + 1.0) * 2; w = 0.25 * s; x = (m[2][1] - m[1][2]) / s; y = (m[0][2] - m[2][0]) / s; z = (m[1][0] - m[0][1]) / s
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2; w = (m[2][1] - m[1][2]) / s; x = 0.25 * s; y = (m[0][1] + m[1][0]) / s; z = (m[0][2] + m[2][0]) / s
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2; w = (m[0][2] - m[2][0]) / s; x = (m[0][1] + m[1][0]) / s; y = 0.25 * s; z = (m[1][2] + m[2][1]) / s
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2; w = (m[1][0] - m[0][1]) / s; x = (m[0][2] + m[2][0]) / s; y = (m[1][2] + m[2][1]) / s; z = 0.25 * s
    n = math.sqrt(w*w + x*x + y*y + z*z)
    return x / n, y / n, z / n, w / n
lines = ["v%d %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n" % ((k, r[3], r[7], r[11]) + quat(r)) for k, r in enumerate(rows)]
open(sys.argv[2] + "/graph_sorted.txt", "w").writelines(lines)
random.seed(3)
random.shuffle(lines)
open(sys.argv[2] + "/graph_shuffled.txt", "w").writelines(lines)
PY2
check map_graph_sorted 0 "" -- "$CARAT" map --frames "$seqdir" --poses "$scratch/graph_sorted.txt" --poses-format graph --perturb-m 0.1 --perturb-deg 1 --json --out "$scratch/graph_sorted_out.txt"
cp "$scratch/out" "$scratch/graph_sorted.json"
check map_graph_shuffled 0 "" -- "$CARAT" map --frames "$seqdir" --poses "$scratch/graph_shuffled.txt" --poses-format graph --perturb-m 0.1 --perturb-deg 1 --json --out "$scratch/graph_shuffled_out.txt"
expect map_graph_by_id "$(json_field "$scratch/out" "abs(j['ate_rmse'] - $(json_field "$scratch/graph_sorted.json" "j['ate_rmse']")) < 1e-12 and j['ate_rmse'] < 0.25 * j['initial_ate_rmse']")"
expect map_graph_out_ids "$(python3 -c "import sys; print([l.split()[0] for l in open(sys.argv[1])] == ['v%d' % k for k in range(20)])" "$scratch/graph_shuffled_out.txt")"
head -n 19 "$scratch/graph_sorted.txt" >"$scratch/graph_missing.txt"
sed -n 20p "$scratch/graph_sorted.txt" | sed 's/^v19/v77/' >>"$scratch/graph_missing.txt"
check map_graph_missing_id 1 "graph_missing.txt: has no vertex v19 for frame $seqdir/000019.bin" -- "$CARAT" map --frames "$seqdir" --poses "$scratch/graph_missing.txt" --poses-format graph
# Degenerate scans (a plane) are refused by map as by align, naming the file.
mkdir -p "$scratch/plane_frames"
python3 - "$scratch/plane_frames" <<'PY2'
import random, struct, sys
random.seed(2)
for k in range(4):
    with open("%s/%06d.bin" % (sys.argv[1], k), "wb") as f:
        for _ in range(20000):
            f.write(struct.pack("<4f", random.uniform(-20, 20), random.uniform(-20, 20), random.gauss(0, 0.01), 0))
PY2
printf '1 0 0 %s 0 1 0 0 0 0 1 0\n' 0 0.2 0.4 0.6 >"$scratch/plane_poses.txt"
check map_degenerate 1 "000000.bin: the scan fixes only 3 of 6 degrees of freedom" -- "$CARAT" map --frames "$scratch/plane_frames" --poses "$scratch/plane_poses.txt" --perturb-m 0.2


# The command line itself: unknown subcommands, control bytes and empty paths.
check unknown_subcommand 2 "carat: usage error: unknown subcommand 'frobnicate' (valid: demo, solve-g2o" -- "$CARAT" frobnicate
check choice_control_bytes 2 "--initial" -- "$CARAT" demo --initial "$(printf 'drift\a\n\033[2J')"
if grep -qP '[\x00-\x08\x0b-\x1f\x7f]' "$scratch/err"; then echo "FAIL control bytes echoed"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
check empty_input_path 2 "the path is empty" -- "$CARAT" solve-g2o ""
check empty_estimate 2 "--estimate: the path is empty" -- "$CARAT" ate --estimate "" --reference "$scratch/ref.kitti"
check empty_out 2 "--out: the path is empty" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --out ""
check threads_over_cores 0 "" -- "$CARAT" simulate --out "$scratch/threads" --frames 3 --threads 1024
[[ ! -s "$scratch/err" ]] && pass=$((pass + 1)) || { echo "FAIL --threads above the cores printed: $(head -c 200 "$scratch/err")"; fail=$((fail + 1)); }
# Options that would be ignored are refused.
check map_pgo_sampling 2 "--sampling does not apply to --method pgo" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --method pgo --sampling lossless
check map_lossless_residuals 2 "--residuals does not apply to --sampling lossless" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --sampling lossless --residuals 64
check g2o_scale_without_loss 2 "--loss-scale does not apply to --loss none" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --loss-scale 5
check g2o_gn_growth 2 "--trust-region-growth does not apply to --method gn" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --method gn --trust-region-growth 3
check g2o_gn_anderson 2 "--anderson-memory does not apply to --method gn" -- "$CARAT" solve-g2o "$scratch/tiny.g2o" --method gn --anderson-memory 3
check ate_kitti_max_difference 2 "--max-difference does not apply" -- "$CARAT" ate --estimate "$scratch/ref.kitti" --reference "$scratch/ref.kitti" --max-difference 0.1
check coreset_too_slow 2 "would take about" -- "$CARAT" coreset-check --rows 5000 --dim 64 --clusters 2147 --trials 1
check paper_missing_data 2 "--data $scratch/nothing-here: not a folder" -- "$CARAT" paper --quick --data "$scratch/nothing-here" --out "$scratch/never-paper"
mkdir -p "$scratch/fifo_data/kitti07_seq5" && mkfifo "$scratch/fifo_data/kitti07_seq5/graph.txt"
check paper_fifo_data 1 "graph.txt: is not a regular file" -- timeout 60 "$CARAT" paper --quick --data "$scratch/fifo_data" --out "$scratch/never-paper"

# Standard output as an output, and a failing standard output: nothing is replaced.
check out_stdout_pipe 0 "" -- bash -c "'$CARAT' solve-g2o '$scratch/tiny.g2o' --out /dev/stdout | cat"
expect out_stdout_pipe_content "$(grep -c '^VERTEX_SE3:QUAT' "$scratch/out" | grep -qx 3 && echo True)"
check out_stdout_file 0 "" -- bash -c "'$CARAT' solve-g2o '$scratch/tiny.g2o' --out /dev/stdout >'$scratch/both.txt'"
expect out_stdout_file_keeps_report "$(grep -q '^wrote /dev/stdout' "$scratch/both.txt" && grep -q '^VERTEX_SE3:QUAT 2 ' "$scratch/both.txt" && echo True)"
echo "old output" >"$scratch/kept.g2o"
check full_stdout_keeps_out 1 "cannot write the output to standard output: No space left on device; no output was written" -- bash -c "'$CARAT' solve-g2o '$scratch/tiny.g2o' --out '$scratch/kept.g2o' >/dev/full"
expect full_stdout_old_output "$([[ $(cat "$scratch/kept.g2o") == "old output" ]] && echo True)"
check full_stdout_no_folder 1 "cannot write the output to standard output" -- bash -c "'$CARAT' simulate --out '$scratch/never-full' --frames 3 >/dev/full"
expect full_stdout_folder_absent "$([[ ! -e "$scratch/never-full" ]] && ! ls -A "$scratch" | grep -q '^\.never-full' && echo True)"
for sig in QUIT USR1 ALRM; do
  "$CARAT" simulate --out "$scratch/sig$sig" --frames 1500 >/dev/null 2>&1 &
  victim=$!
  for _ in $(seq 1 200); do ls -A "$scratch" | grep -q "^\.sig$sig\.tmp-" && break; sleep 0.05; done
  kill -"$sig" $victim
  wait $victim
  if ls -A "$scratch" | grep -q "^\.sig$sig" || [[ -e "$scratch/sig$sig" ]]; then echo "FAIL SIG$sig left temporaries"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
done
check map_out_as_frame 2 "would become a frame of --frames" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --out "$seqdir/000020.bin"

# Scan folders: natural order (2.bin before 10.bin), hidden files skipped.
mkdir -p "$scratch/natural"
for k in $(seq 0 19); do cp "$seqdir/$(printf %06d "$k").bin" "$scratch/natural/$k.bin"; done
cp "$seqdir/000003.bin" "$scratch/natural/.hidden.bin"
check map_natural_order 0 "" -- "$CARAT" map --frames "$scratch/natural" --poses "$seqdir/poses.txt" --perturb-m 0.1 --perturb-deg 1 --json
expect map_natural_order_ate "$(json_field "$scratch/out" "j['frames'] == 20 and j['ate_rmse'] < 0.25 * j['initial_ate_rmse']")"
# Georeferenced poses (10^8 m from the origin) are solved as well as poses near it.
python3 -c "
import sys
for line in open(sys.argv[1]):
    v = [float(x) for x in line.split()]
    v[3] += 1e8; v[7] += 1e8
    print(' '.join(repr(x) for x in v))" "$seqdir/poses.txt" >"$scratch/geo.txt"
check map_georeferenced 0 "" -- "$CARAT" map --frames "$seqdir" --poses "$scratch/geo.txt" --perturb-m 0.1 --perturb-deg 1 --json
expect map_georeferenced_ate "$(json_field "$scratch/out" "j['ate_rmse'] < 0.25 * j['initial_ate_rmse'] and j['iterations'] > 1")"
# ATE: graph.txt against graph.txt pairs by id; a straight-line estimate keeps a settled rotation.
printf 'v0 0 0 0 0 0 0 1\nv1 1 0 0 0 0 0 1\nv5 2 1 0 0 0 0 1\nv9 3 1 1 0 0 0 1\n' >"$scratch/ids_a.txt"
printf 'v9 3 1 1 0 0 0 1\nv0 0 0 0 0 0 0 1\nv1 1 0 0 0 0 0 1\nv7 9 9 9 0 0 0 1\nv5 2 1 0 0 0 0 1\n' >"$scratch/ids_b.txt"
check ate_graph_by_id 0 "" -- "$CARAT" ate --estimate "$scratch/ids_a.txt" --reference "$scratch/ids_b.txt" --format graph --json
expect ate_graph_by_id_pairs "$(json_field "$scratch/out" "j['association'] == 'id' and j['num_poses'] == 4 and j['rmse'] < 1e-9")"
for k in 0 1 2 3 4 5 6 7 8 9; do echo "1 0 0 $k 0 1 0 0 0 0 1 0"; done >"$scratch/line.kitti"
for k in 0 1 2 3 4 5 6 7 8 9; do echo "1 0 0 $k 0 1 0 0.0$((k % 3)) 0 0 1 -0.0$((k % 2))"; done >"$scratch/wiggle.kitti"
check ate_straight_line 0 "" -- "$CARAT" ate --estimate "$scratch/line.kitti" --reference "$scratch/wiggle.kitti" --json
expect ate_straight_line_rotation "$(json_field "$scratch/out" "j['rotation_max_deg'] < 1.0")"
# Lying or inconsistent cloud files.
python3 - "$scratch" <<'PY2'
import struct, sys
d = sys.argv[1]
pts = b"".join(struct.pack('<3f', i, i % 7, i % 3) for i in range(40))
open(d + "/extra.pcd", "wb").write(b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 39\nDATA binary\n" + pts)
open(d + "/uchar.pcd", "wb").write(b"FIELDS x y z\nSIZE 1 4 4\nTYPE U F F\nPOINTS 2\nDATA ascii\n300 1 2\n4 5 6\n")
open(d + "/tail.pcd", "wb").write(b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii\n1 2 3\nfoo\n")
PY2
check pcd_extra_data 1 "extra.pcd: the file holds 12 bytes after the 39 points the header announces" -- "$CARAT" align --target "$scratch/extra.pcd" --source "$scratch/extra.pcd"
check pcd_ascii_type 1 "uchar.pcd: point 0: x = '300' does not fit its type U1" -- "$CARAT" align --target "$scratch/uchar.pcd" --source "$scratch/uchar.pcd"
check pcd_trailing_text 1 "tail.pcd: line 7: data after the 1 points the header announces" -- "$CARAT" align --target "$scratch/tail.pcd" --source "$scratch/tail.pcd"
# One far outlier does not make a scan degenerate.
cp "$seqdir/000000.bin" "$scratch/outlier.bin"
python3 -c "import struct,sys; open(sys.argv[1],'ab').write(struct.pack('<4f', 10000, 0, 0, 0))" "$scratch/outlier.bin"
check align_far_outlier 0 "" -- "$CARAT" align --target "$seqdir/000000.bin" --source "$scratch/outlier.bin" --json

# Entries of a frames folder that look like frames are refused by name, never skipped.
mkdir -p "$scratch/odd_frames" && cp "$seqdir"/*.bin "$scratch/odd_frames/"
cp "$seqdir/000003.bin" "$scratch/odd_frames/000020.BIN"
check frames_upper_case 1 "odd_frames/000020.BIN: is named like a frame, but frames are read only from *.bin, *.pcd and *.ply (lower case)" -- "$CARAT" map --frames "$scratch/odd_frames" --poses "$seqdir/poses.txt"
rm "$scratch/odd_frames/000020.BIN" && mkdir "$scratch/odd_frames/000020.pcd"
check frames_directory_named_like_a_frame 1 "odd_frames/000020.pcd: is a directory named like a frame file" -- "$CARAT" odometry --frames "$scratch/odd_frames" --out "$scratch/never.txt"
mkdir -p "$scratch/dump/000000" "$scratch/dump/000001" "$scratch/dump/000002"
python3 -c "import struct,sys; [open(sys.argv[1] + '/%06d/points.bin' % k, 'wb').write(struct.pack('<3f', 1, 2, 3) * 40) for k in (0, 2)]" "$scratch/dump"
check frames_dump_without_points 1 "dump/000001: a folder without points.bin among <frame>/points.bin frames" -- "$CARAT" odometry --frames "$scratch/dump" --out "$scratch/never.txt"
# Outputs inside an input folder of frames: one check for every command.
check odometry_out_in_frames 2 "--out $seqdir/odometry.txt lies inside --frames $seqdir, a folder carat reads as input" -- "$CARAT" odometry --frames "$seqdir" --out "$seqdir/odometry.txt"
check map_out_in_frames_subfolder 2 "lies inside --frames" -- "$CARAT" map --frames "$seqdir" --poses "$seqdir/poses.txt" --out "$seqdir/../seq/x.txt"
# Odometry that cannot be trusted (a plane: 3 of 6 directions) fails by name unless allowed.
check odometry_degenerate 1 "odometry of --frames $scratch/plane_frames: 3 of 3 steps cannot be trusted" -- "$CARAT" odometry --frames "$scratch/plane_frames" --out "$scratch/plane_odometry.txt"
expect odometry_degenerate_no_out "$([[ ! -e "$scratch/plane_odometry.txt" ]] && grep -q "plane_frames/000000.bin -> $scratch/plane_frames/000001.bin " "$scratch/err" && echo True)"
check odometry_allow_unconverged 0 "" -- "$CARAT" odometry --frames "$scratch/plane_frames" --out "$scratch/plane_odometry.txt" --allow-unconverged --json
expect odometry_allow_unconverged_listed "$(json_field "$scratch/out" "len(j['unreliable_steps']) == 3 and j['unreliable_steps'][0]['constrained_dof'] == 3")"
# Graph ids: frames named by nanosecond stamps keep them exactly, in what odometry writes and in
# how map pairs a graph file with the frames (and writes it back).
mkdir -p "$scratch/stamped"
for k in $(seq 0 19); do cp "$seqdir/$(printf %06d "$k").bin" "$scratch/stamped/$((1569415453000000000 + 100000000 * k + (k % 2))).bin"; done
check odometry_stamp_ids 0 "" -- "$CARAT" odometry --frames "$scratch/stamped" --out "$scratch/stamped_odometry.txt" --format graph --allow-unconverged
python3 - "$scratch" <<'PY2'
import os, random, sys
d = sys.argv[1]
names = sorted(int(n[:-4]) for n in os.listdir(d + "/stamped"))
rows = dict(zip(range(20), (l.split()[1:] for l in open(d + "/graph_sorted.txt"))))
lines = ["v%d %s\n" % (names[k], " ".join(rows[k])) for k in range(20)]
random.seed(5)
random.shuffle(lines)
open(d + "/stamped_poses.txt", "w").writelines(lines)
PY2
check map_stamp_ids 0 "" -- "$CARAT" map --frames "$scratch/stamped" --poses "$scratch/stamped_poses.txt" --poses-format graph --perturb-m 0.1 --perturb-deg 1 --rounds 1 --json --out "$scratch/stamped_map.txt"
expect map_stamp_ids_paired "$(json_field "$scratch/out" "j['ate_rmse'] < 0.25 * j['initial_ate_rmse']")"
expect stamp_ids_kept "$(python3 -c "
import os, sys
names = sorted(int(n[:-4]) for n in os.listdir(sys.argv[1]))
print([int(l.split()[0][1:]) for l in open(sys.argv[2])] == names == [int(l.split()[0][1:]) for l in open(sys.argv[3])])" "$scratch/stamped" "$scratch/stamped_odometry.txt" "$scratch/stamped_map.txt")"
# simulate-bal: a combination the layout cannot place is a usage error before any work.
check simulate_bal_street_observers 2 "--observations-per-point 58 cannot be placed with --layout street: at most 57" -- "$CARAT" simulate-bal --layout street --cameras 300 --points 300 --observations-per-point 58 --out "$scratch/never.bal"
# Memory estimates count what the coreset holds: 4 GB of rows lift to about 68 GB.
check coreset_lifted_rows 2 "--rows 4000000 --dim 64 needs about" -- "$CARAT" coreset-check --rows 4000000 --dim 64 --target 2000000
expect coreset_lifted_rows_named "$(grep -q "coreset's scratch: 4000000 rows lifted to 2145 numbers each" "$scratch/err" && echo True)"
# `ulimit -v` lowers what is available (not under the sanitizers, whose shadow memory it would
# refuse): 30,000 rows at D = 64 take about 0.8 GB with their lifted rows.
sanitized=$(ldd "$CARAT" 2>/dev/null | grep -c 'libasan\|libubsan')
if [[ $sanitized -eq 0 ]]; then
  check coreset_ulimit 2 "--rows 30000 --dim 64 needs about" -- bash -c "ulimit -v 600000 && exec '$CARAT' coreset-check --rows 30000 --dim 64 --trials 1"
fi
# The linear solver: cameras that share most points make the reduced camera system dense; auto
# factorizes the whole system, and a Schur complement that does not fit is refused with its size.
check simulate_bal_dense 0 "" -- "$CARAT" simulate-bal --layout random --cameras 600 --points 600 --observations-per-point 150 --out "$scratch/dense.bal"
check solve_bal_dense_auto 0 "" -- "$CARAT" solve-bal "$scratch/dense.bal" --max-iterations 0 --json
expect solve_bal_dense_whole_system "$(json_field "$scratch/out" "j['linear_solver'].startswith('cholmod supernodal')")"
if [[ $sanitized -eq 0 ]]; then
  check solve_bal_dense_schur_refused 1 "the solve failed: linear solver: the Schur complement needs about" -- bash -c "ulimit -v 400000 && exec '$CARAT' solve-bal '$scratch/dense.bal' --linear-solver schur --max-iterations 1"
fi

echo "$pass passed, $fail failed"
[[ $fail -eq 0 ]]
