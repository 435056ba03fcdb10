#!/usr/bin/env python3
"""Bundle adjustment with the residual written in numpy: carat against SciPy's large-scale
bundle-adjustment recipe, on carat's synthetic BAL scene (16 cameras x 22,106 points, seed 7,
88,424 observations; `carat simulate-bal --cameras 16 --points 22106 --seed 7`).

SciPy gets its cookbook setup ("Large-scale bundle adjustment in scipy"): the residual of all
observations in numpy, least_squares(method='trf', jac_sparsity=..., x_scale='jac', ftol=1e-4),
finite-difference Jacobians through the sparsity pattern. carat gets the same model in numpy
(bal_numpy.py) as one add_rows() call, one group of two rows per observation over its camera
and its point (points eliminated by the Schur complement), with analytic Jacobians; and, as
references, the same with the residuals alone (carat's central differences) and carat's C++
SnavelyReprojectionBlock. carat runs on one thread, and the numpy model once more on --threads
(SciPy's recipe has no threads to give: its finite differences call the residual column group
after column group, and LSMR multiplies one sparse matrix at a time). Times are wall seconds of
building the problem plus solving it, all in this one process, medians over --repeat runs taken
in turn. Prints a table (or JSON with
--json); exits 1 if a carat solve ends above SciPy's final cost, 77 (skipped) without SciPy.

    PYTHONPATH=build/python python3 examples/python/bundle_adjustment_vs_scipy.py [--points N]
"""

import argparse
import json
import sys
import time

import numpy as np

import carat
from bal_numpy import project


def scipy_solve(scene):
    """SciPy's recipe: residuals of all observations, Jacobian by differences over its pattern."""
    from scipy.optimize import least_squares
    from scipy.sparse import lil_matrix

    cameras, points = scene["cameras"], scene["points"]
    ci, pi, observed = scene["camera_index"], scene["point_index"], scene["observed"]
    nc, npt = len(cameras), len(points)

    def rotate(X, rot_vecs):  # the cookbook's Rodrigues rotation
        theta = np.linalg.norm(rot_vecs, axis=1)[:, np.newaxis]
        with np.errstate(invalid="ignore"):
            v = np.nan_to_num(rot_vecs / theta)
        dot = np.sum(X * v, axis=1)[:, np.newaxis]
        cos_theta, sin_theta = np.cos(theta), np.sin(theta)
        return cos_theta * X + sin_theta * np.cross(v, X) + dot * (1 - cos_theta) * v

    def fun(params):
        camera_params = params[: nc * 9].reshape((nc, 9))
        points_3d = params[nc * 9 :].reshape((npt, 3))
        X, cam = points_3d[pi], camera_params[ci]
        proj = rotate(X, cam[:, :3]) + cam[:, 3:6]
        proj = -proj[:, :2] / proj[:, 2, np.newaxis]
        n = np.sum(proj**2, axis=1)
        r = 1 + cam[:, 7] * n + cam[:, 8] * n**2
        return (proj * (r * cam[:, 6])[:, np.newaxis] - observed).ravel()

    start = time.perf_counter()
    m, n = 2 * len(ci), nc * 9 + npt * 3
    A = lil_matrix((m, n), dtype=int)
    i = np.arange(len(ci))
    for s in range(9):
        A[2 * i, ci * 9 + s] = 1
        A[2 * i + 1, ci * 9 + s] = 1
    for s in range(3):
        A[2 * i, nc * 9 + pi * 3 + s] = 1
        A[2 * i + 1, nc * 9 + pi * 3 + s] = 1
    x0 = np.hstack((cameras.ravel(), points.ravel()))
    result = least_squares(fun, x0, jac_sparsity=A, x_scale="jac", ftol=1e-4, method="trf")
    return {"time_s": time.perf_counter() - start, "final_cost": float(result.cost),
            "evaluations": int(result.nfev), "jacobians": int(result.njev)}


def carat_solve(scene, residuals, threads=1):
    """carat: 'numpy' (analytic Jacobians), 'numpy-differences' (residuals alone) or 'c++'."""
    start = time.perf_counter()
    cameras, points = scene["cameras"], scene["points"]
    ci, pi, observed = scene["camera_index"], scene["point_index"], scene["observed"]
    problem = carat.Problem()
    camera_ids = problem.add_euclidean(cameras)  # one variable per row
    point_ids = problem.add_euclidean(points)
    problem.set_eliminable(point_ids)
    if residuals == "c++":
        problem.add_bal_observations(camera_ids[ci], point_ids[pi], observed)
    else:
        def reprojection(camera, point, rows, jacobians=True):
            # `rows` is 0, 1, ..., 2n - 1 when every observation is asked (each pass of a solve).
            seen = observed if len(rows) == 2 * len(observed) else observed[rows[::2] // 2]
            if not jacobians or residuals == "numpy-differences":
                return project(camera, point, jacobians=False) - seen
            image, J_camera, J_point = project(camera, point)
            return image - seen, [J_camera, J_point]

        problem.add_rows(reprojection, [camera_ids[ci], point_ids[pi]], rows=2 * len(ci), group=2,
                         name="reprojection")
    summary = carat.solve(problem, threads=threads)
    return {"time_s": time.perf_counter() - start, "solve_s": summary.time_s,
            "final_cost": summary.final_cost, "iterations": summary.iterations}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cameras", type=int, default=16)
    parser.add_argument("--points", type=int, default=22106)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--repeat", type=int, default=1, help="runs of each method (medians)")
    parser.add_argument("--threads", type=int, default=2,
                        help="threads of the second numpy run (1: no second run)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    try:
        import scipy  # noqa: F401
    except ImportError:
        print("scipy is not installed (Debian: python3-scipy); skipped")
        return 77
    scene = carat.simulate_bal(cameras=args.cameras, points=args.points, seed=args.seed)
    runs = {}
    for _ in range(args.repeat):  # the methods in turn, so that the machine's load hits each
        runs.setdefault("scipy", []).append(scipy_solve(scene))
        for residuals in ("numpy", "numpy-differences", "c++"):
            runs.setdefault("carat " + residuals, []).append(carat_solve(scene, residuals))
        if args.threads > 1:
            runs.setdefault(f"carat numpy, {args.threads} threads", []).append(
                carat_solve(scene, "numpy", args.threads))
    results = {}
    for name, rs in runs.items():
        results[name] = dict(rs[0])
        for key in ("time_s", "solve_s"):
            if key in rs[0]:
                results[name][key] = float(np.median([r[key] for r in rs]))
    reference = results["scipy"]
    for name, r in results.items():
        r["speedup_vs_scipy"] = reference["time_s"] / r["time_s"]
    ok = all(r["final_cost"] <= reference["final_cost"] for name, r in results.items() if name != "scipy")
    if args.json:
        print(json.dumps({"observations": len(scene["observed"]), "results": results, "ok": ok}, indent=2))
    else:
        print(f"bundle adjustment, {args.cameras} cameras x {args.points} points "
              f"({len(scene['observed'])} observations)")
        print(f"{'method':<26} {'time [s]':>9} {'vs SciPy':>9} {'final cost':>18}")
        for name, r in results.items():
            print(f"{name:<26} {r['time_s']:9.3f} {r['speedup_vs_scipy']:8.1f}x {r['final_cost']:18.6f}")
        print("carat's final costs are at or below SciPy's" if ok else "a carat solve ends ABOVE SciPy")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
