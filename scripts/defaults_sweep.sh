#!/usr/bin/env bash
# The LM defaults measured: how LM begins (--lm-start trust_region: Ceres's radius 1e4;
# gauss_newton: undamped steps while they keep their gain), the trust-region growth (3, 10) and
# factorization reuse (on, off; off also turns off the convergence probe) on the public pose
# graphs and on generated bundle-adjustment problems. One line per run: problem, setting,
# iterations, fresh factorizations, final cost, solve time, termination.
# Usage: scripts/defaults_sweep.sh [BUILD_DIR]
set -euo pipefail
build=${1:-build}
carat="$build/apps/carat/carat"
data="${CARAT_DATA_DIR:-$(dirname "$0")/../../shared/data}/posegraph"
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
field() { python3 -c "import json,sys; j=json.load(sys.stdin); print(j['iterations'], j['iterations'] - j.get('reused_factorizations', 0), '%.9g' % j['final_cost'], '%.3f' % j['solve_time_s' if 'solve_time_s' in j else 'time_s'], j['termination'])"; }
printf '%-28s %-36s %s\n' problem setting "iterations factorizations final_cost time_s termination"
for graph in sphere2500 parking-garage torus3D intel manhattan; do
  [[ -f "$data/$graph.g2o" ]] || continue
  for start in trust_region gauss_newton; do
    for growth in 3 10; do
      for reuse in on off; do
        flags=(--lm-start "$start" --trust-region-growth "$growth")
        [[ $reuse == off ]] && flags+=(--no-factor-reuse)
        printf '%-28s %-36s %s\n' "$graph" "$start, growth $growth, reuse $reuse" \
          "$("$carat" solve-g2o "$data/$graph.g2o" --json "${flags[@]}" | field)"
      done
    done
  done
done
for scene in "ring 100 20000 8 1" "ring 100 20000 8 5" "street 100 20000 6 3" "random 100 20000 6 3" "street 500 60000 5 1"; do
  read -r layout cameras points views noise <<<"$scene"
  file="$scratch/$layout-$cameras-$noise.bal"
  "$carat" simulate-bal --layout "$layout" --cameras "$cameras" --points "$points" \
    --observations-per-point "$views" --start-noise "$noise" --seed 3 --out "$file" >/dev/null
  for start in trust_region gauss_newton; do
    for growth in 3 10; do
      printf '%-28s %-36s %s\n' "$layout $cameras x $points (start x$noise)" \
        "$start, growth $growth" \
        "$("$carat" solve-bal "$file" --json --lm-start "$start" --trust-region-growth "$growth" | field)"
    done
  done
done
