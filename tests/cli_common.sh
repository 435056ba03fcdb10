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

expect() {  # expect NAME CONDITION-RESULT ("True" passes)
  if [[ $2 != "True" ]]; then echo "FAIL $1"; fail=$((fail + 1)); else pass=$((pass + 1)); fi
}
