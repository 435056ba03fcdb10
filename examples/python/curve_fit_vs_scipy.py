#!/usr/bin/env python3
"""The curve fit y = exp(m x + c) defined from numpy, solved by carat and by
scipy.optimize.least_squares on the same data from the same start (m, c) = (0, 0), both given the
analytic Jacobian; optionally beside carat's C++ autodiff block on the same data
(--cpp build/bench/curve_fit_autodiff).

Data: x evenly spaced on [0, 5), y = exp(0.3 x + 0.1) plus N(0, 0.2^2) noise (numpy, --seed).
carat gets one add_rows() call: a function evaluating all rows asked at once, with a `jacobians`
keyword so that cost-only passes skip the Jacobian. SciPy gets its methods 'trf' and 'lm' (both
with jac=..., the dense Jacobian of 2 columns); the faster is the reference. Times are wall
seconds of building the problem plus solving it, the best of --repeat runs taken in turn, with
the seconds and calls spent inside the numpy function.
Prints both results (or JSON with --json); exits 1 when the optima differ by more than 1e-9
(relative), and 77 (skipped) when SciPy is not installed.

    PYTHONPATH=build/python python3 examples/python/curve_fit_vs_scipy.py --rows 1000000 \\
        --repeat 3 --cpp build/bench/curve_fit_autodiff
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import carat

# Tight enough that every solver stops at the optimum to about 1e-12 (relative).
TOLERANCE = 1e-14
# carat's full solve and two compressed solves that end at the full problem's optimum:
# "surrogate" (solve_recompressed's default) and "auto" (a full solve that switches to
# compression where the Gauss-Newton model fails).
MODES = ("full", "surrogate", "auto")


CHUNK = 16384  # rows per numpy operation: arrays that stay in cache run about twice as fast


def curve_data(rows, seed):
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 5.0, rows, endpoint=False)
    return x, np.exp(0.3 * x + 0.1) + rng.normal(scale=0.2, size=rows)


SPENT = {"s": 0.0, "calls": 0}  # time inside exp_model, for where each solver's time goes


def exp_model(mc, x, y, jacobians):
    """r = exp(m x + c) - y and, with jacobians, J (2 x n: dr/dm, dr/dc), chunk by chunk. The
    one residual function both solvers get."""
    start = time.perf_counter()
    n = len(x)
    r = np.empty(n)
    J = np.empty((2, n)) if jacobians else None
    e = J[1] if jacobians else np.empty(n)  # dr/dc = exp(m x + c)
    for s in range(0, n, CHUNK):
        t = slice(s, s + CHUNK)
        np.multiply(x[t], mc[0], out=e[t])
        e[t] += mc[1]
        np.exp(e[t], out=e[t])
        np.subtract(e[t], y[t], out=r[t])
        if jacobians:
            np.multiply(x[t], e[t], out=J[0, t])
    SPENT["s"] += time.perf_counter() - start
    SPENT["calls"] += 1
    return r, J


def timed(solve):
    """solve() with the time and calls spent in exp_model added to its result."""
    SPENT.update(s=0.0, calls=0)
    result = solve()
    result.update(function_s=SPENT["s"], function_calls=SPENT["calls"])
    return result


def carat_solve(X, Y, mode):
    """mode 'full' (carat.solve) or a compressed mode of carat.solve_recompressed."""
    start = time.perf_counter()
    p = carat.Problem()
    v = p.add_euclidean(np.zeros(2))

    def residual(mc, rows, jacobians=True):
        # `rows` is 0, 1, ..., n - 1 when the whole block is evaluated (every full pass).
        x, y = (X, Y) if len(rows) == len(X) else (X[rows], Y[rows])
        r, J = exp_model(mc, x, y, jacobians)
        return (r, [J.T]) if jacobians else r  # J.T: read in place, no copy

    p.add_rows(residual, [v], rows=len(X), name="curve")
    options = dict(function_tolerance=TOLERANCE, gradient_tolerance=TOLERANCE,
                   parameter_tolerance=TOLERANCE, max_iterations=200)
    if mode == "full":
        s = carat.solve(p, **options)
    else:
        s = carat.solve_recompressed(p, mode=mode, **options)
    return {"time_s": time.perf_counter() - start, "final_cost": s.final_cost,
            "iterations": s.iterations, "termination": s.termination, "mc": p.value(v).tolist()}


def scipy_solve(X, Y, method):
    from scipy.optimize import least_squares

    start = time.perf_counter()
    last = {}  # the Jacobian computed beside the last residuals, for jac() at the same point

    def fun(mc):
        r, J = exp_model(mc, X, Y, True)
        last["mc"], last["J"] = mc.copy(), J
        return r

    def jac(mc):
        if "mc" not in last or not np.array_equal(last["mc"], mc):
            fun(mc)
        return last["J"].T

    r = least_squares(fun, np.zeros(2), jac=jac, method=method, ftol=TOLERANCE, xtol=TOLERANCE,
                      gtol=TOLERANCE, max_nfev=1000)
    return {"time_s": time.perf_counter() - start, "final_cost": float(r.cost),
            "iterations": int(r.nfev), "termination": r.message, "mc": r.x.tolist()}


def cpp_solve(program, X, Y, repeat, mode):
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "curve.bin")
        np.stack([X, Y], axis=1).astype("<f8").tofile(path)
        run = subprocess.run([program, path, "--mode", mode, "--repeat", str(repeat),
                              "--function-tolerance", str(TOLERANCE),
                              "--gradient-tolerance", str(TOLERANCE),
                              "--parameter-tolerance", str(TOLERANCE)],
                             capture_output=True, text=True, check=True)
    out = json.loads(run.stdout)
    return {"time_s": out["time_s"], "final_cost": out["final_cost"],
            "iterations": out["iterations"], "termination": out["termination"],
            "mc": [out["m"], out["c"]]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=1000000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeat", type=int, default=1, help="runs of each method (best)")
    parser.add_argument("--cpp", help="build/bench/curve_fit_autodiff, for the C++ reference")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    try:
        import scipy  # noqa: F401
    except ImportError:
        print("scipy is not installed (Debian: python3-scipy); skipped")
        return 77
    X, Y = curve_data(args.rows, args.seed)
    runs = {}
    for _ in range(args.repeat):  # in turn, so that the machine's load hits each alike
        for mode in MODES:
            runs.setdefault(f"carat numpy {mode}", []).append(timed(lambda: carat_solve(X, Y, mode)))
        for method in ("trf", "lm"):
            runs.setdefault(f"scipy {method}", []).append(timed(lambda: scipy_solve(X, Y, method)))
    results = {name: min(rs, key=lambda r: r["time_s"]) for name, rs in runs.items()}
    if args.cpp:
        for mode in MODES:
            results[f"carat C++ autodiff {mode}"] = cpp_solve(args.cpp, X, Y, args.repeat, mode)
    reference = np.array(results["carat numpy full"]["mc"])
    for r in results.values():
        r["max_relative_difference"] = float(np.max(np.abs(np.array(r["mc"]) - reference) /
                                                    np.abs(reference)))
        r["same_optimum"] = r["max_relative_difference"] <= 1e-9
    # SciPy's reference: its fastest method among those that reach the optimum.
    scipy_best = min((r for name, r in results.items() if name.startswith("scipy") and
                      r["same_optimum"]), key=lambda r: r["time_s"], default=None)
    ok = scipy_best is not None and all(r["same_optimum"] for name, r in results.items()
                                        if name.startswith("carat"))
    summary = {"rows": args.rows, "results": results, "ok": ok}
    for mode in MODES:
        ours = results[f"carat numpy {mode}"]
        if scipy_best is not None:
            summary[f"speedup_vs_scipy_{mode}"] = scipy_best["time_s"] / ours["time_s"]
        if f"carat C++ autodiff {mode}" in results:
            summary[f"numpy_vs_cpp_{mode}"] = ours["time_s"] / results[f"carat C++ autodiff {mode}"]["time_s"]
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"curve fit y = exp(m x + c), {args.rows} rows, from (m, c) = (0, 0)")
        print(f"{'method':<28} {'time [s]':>9} {'in numpy':>9} {'calls':>6} {'iters':>6} "
              f"{'final cost':>22} {'m':>20} {'c':>20} {'vs carat':>9}")
        for name, r in results.items():
            numpy_s = f"{r['function_s']:9.4f} {r['function_calls']:6d}" if "function_s" in r else " " * 16
            print(f"{name:<28} {r['time_s']:9.4f} {numpy_s} {r['iterations']:6d} {r['final_cost']:22.15g} "
                  f"{r['mc'][0]:20.15f} {r['mc'][1]:20.15f} {r['max_relative_difference']:9.1e}")
        for mode in MODES:
            if f"speedup_vs_scipy_{mode}" in summary:
                print(f"carat numpy {mode}: {summary[f'speedup_vs_scipy_{mode}']:.1f}x faster than "
                      "SciPy's fastest method at the same optimum")
            if f"numpy_vs_cpp_{mode}" in summary:
                print(f"carat numpy {mode}: {summary[f'numpy_vs_cpp_{mode}']:.2f}x the time of the "
                      "C++ autodiff block")
        print("the optima agree to 1e-9" if ok else "the optima DIFFER by more than 1e-9")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
