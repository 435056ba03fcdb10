# Shared by the CLI test scripts: counters, a scratch folder, and the checks.
# shellcheck shell=bash
set -u
fail=0
pass=0
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT

# A tiny three-pose graph (one loop) that every script solves or breaks.
cat >"$scratch/tiny.g2o" <<'G2O'
VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1
VERTEX_SE3:QUAT 1 0.9 0.1 0 0 0 0.05 0.99875
VERTEX_SE3:QUAT 2 2.1 -0.1 0 0 0 0 1
EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
EDGE_SE3:QUAT 1 2 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
EDGE_SE3:QUAT 0 2 2 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1
G2O

check() {  # check NAME EXPECTED_RC EXPECTED_STDERR_SUBSTRING -- command...
  local name=$1 want_rc=$2 want_err=$3
  shift 4
  "$@" >"$scratch/out" 2>"$scratch/err"
  local rc=$?
  if [[ $rc -ne $want_rc ]]; then
    echo "FAIL $name: exit $rc, expected $want_rc; stderr: $(head -c 300 "$scratch/err")"
    fail=$((fail + 1)); return
  fi
  if [[ -n "$want_err" ]] && ! grep -qF -- "$want_err" "$scratch/err"; then
    echo "FAIL $name: stderr lacks '$want_err': $(head -c 300 "$scratch/err")"
    fail=$((fail + 1)); return
  fi
  if [[ $want_rc -ne 0 ]] && [[ $(wc -l <"$scratch/err") -ne 1 ]]; then
    echo "FAIL $name: expected a one-line error, got $(wc -l <"$scratch/err") lines"
    fail=$((fail + 1)); return
  fi
  pass=$((pass + 1))
}

json_field() {  # json_field FILE EXPR -> prints the value (python3 is on Debian by default)
  python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print($2)" "$1"
}

covariance_file_ok() {  # covariance_file_ok FILE DIM IDS... -> "True" when FILE has one line per
  # id, in order, each the id and a symmetric positive definite DIM x DIM matrix (row-major)
  python3 - "$@" <<'PY'
import sys
path, d, ids = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
lines = [l.split() for l in open(path)]
def spd(a):  # Cholesky without a library
    l = [[0.0] * d for _ in range(d)]
    for i in range(d):
        for j in range(i + 1):
            s = a[i][j] - sum(l[i][k] * l[j][k] for k in range(j))
            if i == j:
                if s <= 0.0: return False
                l[i][i] = s ** 0.5
            else:
                l[i][j] = s / l[j][j]
    return True
ok = [l[0] for l in lines] == ids and all(len(l) == 1 + d * d for l in lines)
for l in lines if ok else []:
    a = [[float(l[1 + r * d + c]) for c in range(d)] for r in range(d)]
    ok = ok and all(a[r][c] == a[c][r] for r in range(d) for c in range(d)) and spd(a)
print(ok)
PY
}

expect() {  # expect NAME CONDITION-RESULT ("True" passes)
  if [[ $2 != "True" ]]; then echo "FAIL $1"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
}
