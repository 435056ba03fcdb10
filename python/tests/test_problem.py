"""carat.Problem from numpy: residual rows written in numpy against carat's C++ blocks and dense
references on the same problems, robust losses, compression, covariance, and bad callbacks."""

import os
import pathlib
import subprocess
import sys
import textwrap
import traceback

import numpy as np
import pytest

import carat
from conftest import se3_exp

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "examples" / "python"))
from bal_numpy import project  # noqa: E402

# Tolerances tight enough that the solves below stop at the optimum to rounding.
TIGHT = dict(function_tolerance=1e-15, gradient_tolerance=1e-14, parameter_tolerance=1e-15,
             max_iterations=100)


def curve_data(n=200, seed=3):
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 5.0, n, endpoint=False)
    return x, np.exp(0.3 * x + 0.1) + rng.normal(scale=0.2, size=n)


def curve_residual(X, Y):
    def residual(mc, rows):
        x, y = X[rows], Y[rows]
        e = np.exp(mc[0] * x + mc[1])
        return y - e, [np.stack([-x * e, -e], axis=1)]

    return residual


def dense_gauss_newton(X, Y, mc):
    for _ in range(100):
        e = np.exp(mc[0] * X + mc[1])
        r, J = Y - e, np.stack([-X * e, -e], axis=1)
        step = np.linalg.solve(J.T @ J, -J.T @ r)
        mc = mc + step
        if np.abs(step).max() < 1e-15:
            break
    return mc, J


def curve_problem(X, Y, residual=None, **rows_options):
    p = carat.Problem()
    v = p.add_euclidean(np.zeros(2))
    p.add_rows(residual or curve_residual(X, Y), [v], rows=len(X), **rows_options)
    return p, v


def test_curve_fit_reaches_the_dense_gauss_newton_optimum():
    X, Y = curve_data()
    p, v = curve_problem(X, Y)
    s = carat.solve(p, **TIGHT)
    assert s.termination == "CONVERGENCE"
    reference, _ = dense_gauss_newton(X, Y, np.array([0.3, 0.1]))
    np.testing.assert_allclose(p.value(v), reference, rtol=1e-10, atol=0)
    r = Y - np.exp(reference[0] * X + reference[1])
    assert s.final_cost == pytest.approx(0.5 * r @ r, rel=1e-12)
    assert "iter" in s.full_report() and s.iterations >= 1


def test_anderson_memory_is_an_option_and_zero_turns_it_off():
    X, Y = curve_data()
    reference, _ = dense_gauss_newton(X, Y, np.array([0.3, 0.1]))
    for memory in (0, 5):
        p, v = curve_problem(X, Y)
        s = carat.solve(p, anderson_memory=memory, **TIGHT)
        assert s.termination == "CONVERGENCE"
        np.testing.assert_allclose(p.value(v), reference, rtol=1e-10, atol=0)
        if memory == 0:
            assert s.to_dict()["accelerated_steps"] == 0
    p, v = curve_problem(X, Y)
    with pytest.raises(ValueError, match=r"^solve\(\): anderson_memory must be in \[0, 64\], got 65$"):
        carat.solve(p, anderson_memory=65)


def test_every_lm_start_reaches_the_same_optimum():
    X, Y = curve_data()
    reference, _ = dense_gauss_newton(X, Y, np.array([0.3, 0.1]))
    for start in ("auto", "gauss_newton", "trust_region"):
        p, v = curve_problem(X, Y)
        s = carat.solve(p, lm_start=start, gauss_newton_phase_min_gain=0.25, **TIGHT)
        assert s.termination == "CONVERGENCE", start
        np.testing.assert_allclose(p.value(v), reference, rtol=1e-9, atol=0)


def test_residuals_alone_get_central_differences_to_the_same_optimum():
    X, Y = curve_data()
    p, v = curve_problem(X, Y, residual=lambda mc, rows: Y[rows] - np.exp(mc[0] * X[rows] + mc[1]))
    carat.solve(p, **TIGHT)
    reference, _ = dense_gauss_newton(X, Y, np.array([0.3, 0.1]))
    np.testing.assert_allclose(p.value(v), reference, rtol=1e-10, atol=0)


def test_covariance_is_the_inverse_gauss_newton_hessian():
    X, Y = curve_data()
    p, v = curve_problem(X, Y)
    carat.solve(p, **TIGHT)
    _, J = dense_gauss_newton(X, Y, p.value(v))
    np.testing.assert_allclose(carat.covariance(p).block(v), np.linalg.inv(J.T @ J), rtol=1e-9)


def test_compressed_solves_reach_the_full_optimum_and_compression_is_exact():
    X, Y = curve_data(n=600)
    full, v = curve_problem(X, Y)
    carat.solve(full, **TIGHT)
    # kRecompress stops once the full cost no longer decreases beyond its rounding: the cost is
    # the optimum's to 1e-12, the values (flat directions of the cost) to 1e-8.
    for mode, rtol in (("surrogate", 1e-10), ("auto", 1e-10), ("recompress", 1e-8)):
        p, w = curve_problem(X, Y)
        s = carat.solve_recompressed(p, mode=mode, **TIGHT)
        np.testing.assert_allclose(p.value(w), full.value(v), rtol=rtol, atol=0)
        assert s.final_cost == pytest.approx(full.cost(), rel=1e-12)
        # The surrogate starts from a sampled problem: 64 of the 600 rows.
        assert s.sampled_start == (mode == "surrogate")
        assert s.sampled_rows == (64 if mode == "surrogate" else 0)
    # Without the sampled start the surrogate compresses first; the same optimum.
    p, w = curve_problem(X, Y)
    s = carat.solve_recompressed(p, sampled_start=False, **TIGHT)
    assert not s.sampled_start and s.recompressions >= 1
    np.testing.assert_allclose(p.value(w), full.value(v), rtol=1e-10, atol=0)
    p, w = curve_problem(X, Y)
    s = carat.solve_recompressed(p, sampled_rows_share=0.5, **TIGHT)
    assert not s.sampled_start  # a block of at most twice its sample (300 of 600) stays whole
    with pytest.raises(ValueError, match=r"sampled_rows_share must be in \[0, 1\], got 2"):
        carat.solve_recompressed(p, sampled_rows_share=2.0)
    # An exact coreset reproduces the cost and gradient at the point it was built at, robust
    # losses per group included.
    p, w = curve_problem(X, Y, loss="cauchy", loss_scale=0.1)
    p.set_value(w, np.array([0.2, 0.3]))
    cost, gradient = p.cost(), p.gradient()
    report = carat.compress(p)
    assert report.rows_after < report.rows_before == 600
    assert p.cost() == pytest.approx(cost, rel=1e-10)
    np.testing.assert_allclose(p.gradient(), gradient, rtol=1e-9)
    report.restore()
    assert p.num_residual_rows == 600


def logged_curve_residual(X, Y, log):
    """curve_residual with the `jacobians` keyword; logs (values, jacobians, rows asked)."""
    def residual(mc, rows, jacobians=True):
        log.append((mc.copy(), jacobians, len(rows)))
        x, y = X[rows], Y[rows]
        e = np.exp(mc[0] * x + mc[1])
        return (y - e, [np.stack([-x * e, -e], axis=1)]) if jacobians else y - e

    return residual


def test_a_cost_pass_asks_for_the_jacobians_its_linearization_then_uses():
    X, Y = curve_data()
    reference, _ = dense_gauss_newton(X, Y, np.array([0.3, 0.1]))
    # Near the optimum every step is accepted: each point is evaluated once, the cost pass at a
    # step's end asking for the Jacobians that the linearization there then takes.
    log = []
    p, v = curve_problem(X, Y, residual=logged_curve_residual(X, Y, log))
    p.set_value(v, np.array([0.25, 0.2]))
    s = carat.solve(p, **TIGHT)
    np.testing.assert_allclose(p.value(v), reference, rtol=1e-10, atol=0)
    points = [tuple(mc) for mc, _, _ in log]
    assert s.unsuccessful_steps == 0 and s.iterations >= 3
    assert len(points) == len(set(points)) == s.iterations + 1
    # ... except the last: the solver announced that cost pass as likely its last (the model's
    # predicted decrease already met the function tolerance), so it asked for none.
    assert all(jacobians for _, jacobians, _ in log[:-1])
    assert not log[-1][1] and "function tolerance" in s.message
    # From (0, 0) Levenberg-Marquardt rejects steps: after Jacobians asked ahead go unused, cost
    # passes skip them again until a step is accepted.
    log.clear()
    p, v = curve_problem(X, Y, residual=logged_curve_residual(X, Y, log))
    s = carat.solve(p, **TIGHT)
    assert s.unsuccessful_steps >= 2
    assert any(not jacobians for _, jacobians, _ in log)
    # The same optimum, to the last bit, as a function without the keyword (whose Jacobians
    # carat always keeps).
    q, w = curve_problem(X, Y)
    carat.solve(q, **TIGHT)
    np.testing.assert_array_equal(p.value(v), q.value(w))
    np.testing.assert_allclose(p.value(v), reference, rtol=1e-10, atol=0)


def refilling_curve_residual(X, Y, r_out, J_out):
    """curve_residual writing into the same two arrays on every call (views of them returned)."""
    def residual(mc, rows):
        n = len(rows)
        e = np.exp(mc[0] * X[rows] + mc[1])
        np.subtract(Y[rows], e, out=r_out[:n])
        J_out[:n, 0], J_out[:n, 1] = -X[rows] * e, -e
        return r_out[:n], [J_out[:n]]

    return residual


def test_a_function_that_refills_its_arrays_is_never_read_stale():
    X, Y = curve_data(n=600)
    r_out, J_out = np.empty(len(X)), np.empty((len(X), 2))
    refilling = refilling_curve_residual(X, Y, r_out, J_out)
    p, v = curve_problem(X, Y, residual=refilling)
    q, w = curve_problem(X, Y)
    for problem, variable in ((p, v), (q, w)):
        problem.set_value(variable, np.array([0.2, 0.3]))
    cost, gradient = p.cost(), p.gradient()
    assert cost == q.cost() and np.array_equal(gradient, q.gradient())
    report = carat.compress(p)  # evaluates the kept rows alone: the arrays' first rows change
    assert p.cost() == pytest.approx(cost, rel=1e-10)
    report.restore()
    assert p.cost() == cost and np.array_equal(p.gradient(), gradient)
    refilling(np.array([1.0, -1.0]), np.arange(len(X)))  # the user calls it, at other values
    assert p.cost() == cost
    carat.solve_recompressed(p, **TIGHT)
    carat.solve_recompressed(q, **TIGHT)
    np.testing.assert_array_equal(p.value(v), q.value(w))
    # The same function (the same two arrays) for both halves of the rows, in two add_rows()
    # calls of one problem: each half reads its own numbers.
    half = len(X) // 2
    two = carat.Problem()
    u = two.add_euclidean(np.zeros(2))
    two.add_rows(lambda mc, rows: refilling(mc, rows), [u], rows=half)
    two.add_rows(lambda mc, rows: refilling(mc, rows + half), [u], rows=len(X) - half)
    for problem, variable in ((two, u), (q, w)):
        problem.set_value(variable, np.array([0.2, 0.3]))
    assert two.cost() == pytest.approx(q.cost(), rel=1e-12)
    np.testing.assert_allclose(two.gradient(), q.gradient(), rtol=1e-12)
    carat.solve(two, **TIGHT)
    carat.solve(q, **TIGHT)
    np.testing.assert_allclose(two.value(u), q.value(w), rtol=1e-12)


def test_rows_of_many_blocks_from_refilled_arrays_reach_the_same_solution():
    # One variable per group (a block each), two rows per group: x_g - a_g and 2 (x_g - b_g)^2.
    rng = np.random.default_rng(4)
    groups = 50
    a, b = rng.normal(size=groups), rng.normal(size=groups)
    buffers = np.empty((2 * groups,)), np.empty((2 * groups, 1))

    def rows_of(x, rows, out=None):
        g = rows[::2] // 2
        r = np.empty(len(rows)) if out is None else out[0][:len(rows)]
        J = np.empty((len(rows), 1)) if out is None else out[1][:len(rows)]
        d = x[:, 0] - b[g]
        r[0::2], r[1::2] = x[:, 0] - a[g], 2.0 * d * d
        J[0::2, 0], J[1::2, 0] = 1.0, 4.0 * d
        return r, [J]

    solutions = []
    for out in (None, buffers):
        p = carat.Problem()
        ids = p.add_euclidean(np.zeros((groups, 1)))
        p.add_rows(lambda x, rows, out=out: rows_of(x, rows, out), [ids], rows=2 * groups,
                   group=2)
        s = carat.solve(p, **TIGHT)
        assert s.termination == "CONVERGENCE"
        solutions.append(p.value(ids))
    np.testing.assert_array_equal(solutions[0], solutions[1])


def test_data_changed_between_calls_is_read_afresh():
    X, Y = curve_data()
    p, v = curve_problem(X, Y)
    carat.solve(p, **TIGHT)
    Y[:] = np.exp(0.5 * X - 0.2)  # the data the function reads, changed in place
    r = Y - np.exp(p.value(v)[0] * X + p.value(v)[1])
    assert p.cost() == pytest.approx(0.5 * r @ r, rel=1e-12)
    s = carat.solve(p, **TIGHT)
    assert s.termination == "CONVERGENCE" and s.final_cost < 1e-20
    np.testing.assert_allclose(p.value(v), [0.5, -0.2], rtol=1e-9)


def pose_chain(n=6, seed=5):
    """Poses on a gently turning line, noisy odometry plus two loop closures (i, j, T_i_j)."""
    rng = np.random.default_rng(seed)
    truth = [se3_exp([0.0, 0.0, 0.1 * k], [2.0 * k, 0.3 * k, 0.0]) for k in range(n)]
    edges = [(k, k + 1) for k in range(n - 1)] + [(0, n - 1), (1, n - 2)]
    measured = []
    for i, j in edges:
        noise = se3_exp(rng.normal(scale=0.01, size=3), rng.normal(scale=0.05, size=3))
        measured.append((i, j, np.linalg.inv(truth[i]) @ truth[j] @ noise))
    start = [truth[0]]
    for k in range(1, n):
        start.append(start[-1] @ measured[k - 1][2])
    return start, measured


INFORMATION = np.diag([100.0, 100.0, 100.0, 400.0, 400.0, 400.0])


def relative_pose_residual(T_ij):
    """RelativePoseBlock's residual in numpy, one group of 6 rows per edge."""
    U = np.sqrt(np.diag(INFORMATION))

    def residual(T_i, T_j, rows):
        edge = rows[::6] // 6
        R_i, R_j, t_i, t_j = T_i[:, :3, :3], T_j[:, :3, :3], T_i[:, :3, 3], T_j[:, :3, 3]
        e_t = np.einsum("gba,gb->ga", R_i, t_j - t_i) - T_ij[edge, :3, 3]
        M = np.einsum("gba,gcb,gcd->gad", T_ij[edge, :3, :3], R_i, R_j)
        w = np.sqrt(1.0 + np.trace(M, axis1=1, axis2=2))  # 2 cos(angle / 2) > 0 here
        e_r = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]],
                       axis=1) / w[:, None]
        return (np.concatenate([e_t, e_r], axis=1) * U).ravel()

    return residual


def pose_graph_problems(loss, loss_per):
    start, measured = pose_chain()
    cpp, rows = carat.Problem(), carat.Problem()
    ids = [(cpp.add_se3(T), rows.add_se3(T)) for T in start]
    for p, k in ((cpp, 0), (rows, 1)):
        p.set_constant(ids[0][k])
    for i, j, T_ij in measured:
        cpp.add_relative_pose(ids[i][0], ids[j][0], T_ij, INFORMATION, loss=loss, loss_scale=0.5)
    T_ij = np.array([m[2] for m in measured])
    rows.add_rows(relative_pose_residual(T_ij), [np.array([m[0] for m in measured]),
                                                 np.array([m[1] for m in measured])],
                  rows=6 * len(measured), group=6, loss=loss, loss_scale=0.5, loss_per=loss_per,
                  name="edges")
    return cpp, rows, [k[0] for k in ids], [k[1] for k in ids]


@pytest.mark.parametrize("loss, loss_per", [("none", "group"), ("huber", "group"), ("huber", "block")])
def test_pose_graph_rows_match_carats_relative_pose_blocks(loss, loss_per):
    cpp, rows, cpp_ids, rows_ids = pose_graph_problems(loss, loss_per)
    assert rows.num_residual_blocks == 7  # one block per edge (distinct pair of poses)
    assert rows.cost() == pytest.approx(cpp.cost(), rel=1e-12)
    np.testing.assert_allclose(rows.gradient(), cpp.gradient(), rtol=1e-6, atol=1e-6)
    s_cpp, s_rows = carat.solve(cpp, **TIGHT), carat.solve(rows, **TIGHT)
    assert s_cpp.termination == s_rows.termination == "CONVERGENCE"
    assert s_rows.final_cost == pytest.approx(s_cpp.final_cost, rel=1e-10)
    np.testing.assert_allclose(rows.value(rows_ids), cpp.value(cpp_ids), rtol=0, atol=1e-10)


def se2_log_residual(T_ij, information):
    """RelativePoseSE2Block's residual in numpy: [vx, vy, w] of Log(T_ij^-1 T_i^-1 T_j), whitened."""
    U = np.linalg.cholesky(information).T  # U^T U = information

    def residual(T_i, T_j, rows):
        edge = rows[::3] // 3
        E = np.linalg.inv(T_ij[edge]) @ np.linalg.inv(T_i) @ T_j
        w = np.arctan2(E[:, 1, 0], E[:, 0, 0])
        small = np.abs(w) < 1e-9
        safe = np.where(small, 1.0, w)
        a = np.where(small, 1.0 - w * w / 6.0, np.sin(safe) / safe)
        b = np.where(small, w / 2.0, (1.0 - np.cos(safe)) / safe)
        t = E[:, :2, 2]
        det = a * a + b * b  # V = [[a, -b], [b, a]], V^-1 = [[a, b], [-b, a]] / det
        v = np.stack([(a * t[:, 0] + b * t[:, 1]) / det, (-b * t[:, 0] + a * t[:, 1]) / det], axis=1)
        return (np.concatenate([v, w[:, None]], axis=1) @ U.T).ravel()

    return residual

def test_per_edge_rows_pass_the_block_checker_and_never_refill_an_array_the_function_kept():
    # One block per edge (a group of six rows each): check_blocks runs the row-contract checker
    # on them (subsets of a group's rows, extracts, a group loss), and every argument array the
    # function keeps must still hold the values it was called with after the solve.
    start, measured = pose_chain()
    T_ij = np.array([m[2] for m in measured])
    edge_residual = relative_pose_residual(T_ij)
    kept = []

    def residual(T_i, T_j, rows):
        kept.append((T_i, T_i.copy(), T_j, T_j.copy()))
        return edge_residual(T_i, T_j, rows)

    cpp, _, cpp_ids, _ = pose_graph_problems("huber", "group")
    p = carat.Problem()
    ids = [p.add_se3(T) for T in start]
    p.set_constant(ids[0])
    p.add_rows(residual, [np.array([ids[m[0]] for m in measured]),
                          np.array([ids[m[1]] for m in measured])],
               rows=6 * len(measured), group=6, loss="huber", loss_scale=0.5, name="edges")
    s, s_cpp = carat.solve(p, check_blocks=True, **TIGHT), carat.solve(cpp, **TIGHT)
    assert s.termination == "CONVERGENCE" and len(kept) > 3
    assert s.final_cost == pytest.approx(s_cpp.final_cost, rel=1e-10)
    np.testing.assert_allclose(p.value(ids), cpp.value(cpp_ids), rtol=0, atol=1e-10)
    for T_i, at_call_i, T_j, at_call_j in kept:
        assert np.array_equal(T_i, at_call_i) and np.array_equal(T_j, at_call_j)



def test_se2_rows_match_carats_relative_pose_se2_blocks():
    rng = np.random.default_rng(8)
    truth = [np.array([1.5 * k, 0.4 * k, 0.15 * k]) for k in range(5)]

    def matrix(x, y, theta):
        return np.array([[np.cos(theta), -np.sin(theta), x], [np.sin(theta), np.cos(theta), y], [0, 0, 1.0]])

    edges = [(k, k + 1) for k in range(4)] + [(0, 4), (1, 3)]
    information = np.array([[50.0, 5.0, 0.0], [5.0, 40.0, 2.0], [0.0, 2.0, 200.0]])
    T_ij = np.array([np.linalg.inv(matrix(*truth[i])) @ matrix(*truth[j]) @ matrix(*rng.normal(scale=0.05, size=3))
                     for i, j in edges])
    cpp, rows = carat.Problem(), carat.Problem()
    start = [t + rng.normal(scale=0.1, size=3) for t in truth]
    ids = [(cpp.add_se2(x), rows.add_se2(matrix(*x))) for x in start]
    cpp.set_constant(ids[0][0])
    rows.set_constant(ids[0][1])
    for (i, j), T in zip(edges, T_ij):
        cpp.add_relative_pose_se2(ids[i][0], ids[j][0], T, information)
    rows.add_rows(se2_log_residual(T_ij, information), [np.array([e[0] for e in edges]), np.array([e[1] for e in edges])],
                  rows=3 * len(edges), group=3)
    assert rows.cost() == pytest.approx(cpp.cost(), rel=1e-12)
    carat.solve(cpp, **TIGHT)
    carat.solve(rows, **TIGHT)
    np.testing.assert_allclose(rows.value([k[1] for k in ids]), cpp.value([k[0] for k in ids]), rtol=0, atol=1e-10)


def test_bundle_adjustment_rows_match_carats_reprojection_blocks():
    scene = carat.simulate_bal(cameras=3, points=30, observations_per_point=3, seed=2)
    ci, pi, observed = scene["camera_index"], scene["point_index"], scene["observed"]
    problems, calls = [], []
    for kind in ("c++", "numpy"):
        p = carat.Problem()
        cameras, points = p.add_euclidean(scene["cameras"]), p.add_euclidean(scene["points"])
        p.set_eliminable(points)
        if kind == "c++":
            p.add_bal_observations(cameras[ci], points[pi], observed)
        else:
            def reprojection(camera, point, rows):
                calls.append(len(rows))
                image, J_camera, J_point = project(camera, point)
                return image - observed[rows[::2] // 2], [J_camera, J_point]

            p.add_rows(reprojection, [cameras[ci], points[pi]], rows=2 * len(ci), group=2)
        problems.append((p, cameras, points))
    (cpp, c1, x1), (rows, c2, x2) = problems
    assert rows.cost() == pytest.approx(cpp.cost(), rel=1e-12)
    np.testing.assert_allclose(rows.gradient(), cpp.gradient(), rtol=1e-9, atol=1e-9)
    # Stopped before the cost changes only by rounding: past that point, steps along the
    # similarity gauge (which leaves the cost unchanged) follow the rounding of each Jacobian.
    # For the same reason the trust region from the start: the Gauss-Newton phase damps the
    # gauge by 1e-10 only, so two roundings of one Jacobian drift apart along it (by ~1e-6).
    options = dict(TIGHT, function_tolerance=1e-10, lm_start="trust_region")
    s_cpp, s_rows = carat.solve(cpp, **options), carat.solve(rows, **options)
    assert s_rows.final_cost == pytest.approx(s_cpp.final_cost, rel=1e-12)
    assert s_rows.iterations == s_cpp.iterations
    # One call evaluates all 90 blocks (one per observation): two calls an iteration at most
    # (linearization, trial cost), each asked for every row.
    assert rows.num_residual_blocks == 90
    assert len(calls) <= 2 * (s_rows.iterations + 1) + 4 and set(calls) == {180}
    np.testing.assert_allclose(rows.value(c2), cpp.value(c1), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(rows.value(x2), cpp.value(x1), rtol=1e-10, atol=1e-10)


def test_threads_reading_one_batch_side_by_side_reach_the_one_thread_solution():
    # Enough observations that two threads split every pass, each reading the batch's kept
    # evaluation while the other may replace it (at each new point's first block).
    scene = carat.simulate_bal(cameras=4, points=3000, observations_per_point=3, seed=5)
    ci, pi, observed = scene["camera_index"], scene["point_index"], scene["observed"]
    results = []
    for threads in (1, 2, 2):
        p = carat.Problem()
        cameras, points = p.add_euclidean(scene["cameras"]), p.add_euclidean(scene["points"])
        p.set_eliminable(points)

        def reprojection(camera, point, rows):
            image, J_camera, J_point = project(camera, point)
            return image - observed[rows[::2] // 2], [J_camera, J_point]

        p.add_rows(reprojection, [cameras[ci], points[pi]], rows=2 * len(ci), group=2)
        s = carat.solve(p, threads=threads, function_tolerance=1e-10, lm_start="trust_region")
        assert s.termination == "CONVERGENCE"
        results.append((s.final_cost, p.value(cameras), p.value(points)))
    for cost, camera_values, point_values in results[1:]:  # results do not depend on threads
        assert cost == results[0][0]
        np.testing.assert_array_equal(camera_values, results[0][1])
        np.testing.assert_array_equal(point_values, results[0][2])


def test_gicp_block_recovers_the_relative_pose():
    rng = np.random.default_rng(4)
    target = rng.uniform(-5.0, 5.0, size=(60, 3))
    T_target_source = se3_exp([0.05, -0.02, 0.1], [0.3, -0.2, 0.1])
    source = (target - T_target_source[:3, 3]) @ T_target_source[:3, :3]  # exact correspondences
    covariances = np.tile(np.diag([0.01, 0.02, 0.03]), (60, 1, 1))
    p = carat.Problem()
    i, j = p.add_se3(np.eye(4)), p.add_se3(np.eye(4))
    p.set_constant(i)
    p.add_gicp(i, j, target, covariances, source, covariances)
    carat.solve(p, **TIGHT)
    np.testing.assert_allclose(p.value(j), T_target_source, atol=1e-10)
    # The compressed solve's start takes the block as its lossless rows (at most 13 of 180): the
    # same pose.
    p.set_value(j, np.eye(4))
    s = carat.solve_recompressed(p, **TIGHT)
    assert s.exact_form_blocks == 1 and 1 <= s.sampled_rows <= 13
    np.testing.assert_allclose(p.value(j), T_target_source, atol=1e-10)
    s = carat.solve_recompressed(p, exact_forms=False, **TIGHT)
    assert s.exact_form_blocks == 0


@pytest.mark.parametrize("jacobian", ["analytic", "differences"])
def test_point_alignment_in_numpy_recovers_the_pose(jacobian):
    """One block of 3 rows per point over one SE(3) pose: r = R p + t - q."""
    rng = np.random.default_rng(6)
    p_source = rng.uniform(-3.0, 3.0, size=(40, 3))
    T_true = se3_exp([0.2, -0.1, 0.3], [1.0, -2.0, 0.5])
    q_target = p_source @ T_true[:3, :3].T + T_true[:3, 3]

    def residual(T, rows):
        k = rows[::3] // 3
        Rp = p_source[k] @ T[:3, :3].T
        r = (Rp + T[:3, 3] - q_target[k]).ravel()
        if jacobian == "differences":
            return r
        # Right perturbation T Exp([omega, v]): d/d omega = -R [p]x, d/d v = R.
        px = np.zeros((len(k), 3, 3))
        px[:, 0, 1], px[:, 0, 2], px[:, 1, 2] = -p_source[k, 2], p_source[k, 1], -p_source[k, 0]
        px -= px.transpose(0, 2, 1)
        J = np.concatenate([-T[:3, :3] @ px, np.broadcast_to(T[:3, :3], (len(k), 3, 3))], axis=2)
        return r, [J]

    p = carat.Problem()
    v = p.add_se3(np.eye(4))
    p.add_rows(residual, [v], rows=3 * len(p_source), group=3)
    carat.solve(p, **TIGHT)
    np.testing.assert_allclose(p.value(v), T_true, atol=1e-10)


# --- Bad callbacks: a clear error naming the block, never a crash or a hang.


def test_an_exception_in_a_residual_reaches_the_user_with_its_traceback():
    X, Y = curve_data()

    def broken_residual(mc, rows):
        return {}["no such key"]

    p, _ = curve_problem(X, Y, residual=broken_residual)
    with pytest.raises(KeyError) as raised:
        carat.solve(p)
    frames = [frame.name for frame in traceback.extract_tb(raised.value.__traceback__)]
    assert "broken_residual" in frames


@pytest.mark.parametrize(
    "returned, message",
    [
        (lambda n: np.zeros(n - 1), r"curve: the residual function returned residuals of shape \(199,\); "
                                    r"expected \(200,\), one per row asked"),
        (lambda n: np.zeros(n, dtype=np.float32), "curve: the residual function returned residuals of "
                                                  "dtype float32; expected float64"),
        (lambda n: (np.zeros(n), [np.zeros((n, 3))]), r"curve: the residual function returned the "
                                                      r"Jacobian of argument 1 \(euclidean\(2\)\) of shape "
                                                      r"\(200, 3\); expected \(200, 2\)"),
        (lambda n: (np.zeros(n), [np.zeros((n, 2)), np.zeros((n, 2))]),
         "curve: the residual function returned 2 Jacobians for 1 variables"),
        (lambda n: "residuals", "curve: the residual function returned residuals of dtype <U9"),
    ],
)
def test_a_residual_of_the_wrong_shape_or_dtype_is_a_value_error_naming_the_block(returned, message):
    p, _ = curve_problem(*curve_data(), residual=lambda mc, rows: returned(len(rows)), name="curve")
    with pytest.raises(ValueError, match=message):
        carat.solve(p)
    with pytest.raises(ValueError, match=message):  # the same again: the problem stays usable
        carat.solve(p)


def test_a_non_finite_residual_is_a_carat_error_naming_the_block_and_row():
    X, Y = curve_data()

    def residual(mc, rows):
        r, J = curve_residual(X, Y)(mc, rows)
        r[rows == 17] = np.nan
        return r, J

    p, _ = curve_problem(X, Y, residual=residual, name="curve")
    with pytest.raises(carat.Error, match=r"curve.*row 17"):
        carat.solve(p)


def test_bad_arguments_are_named():
    p = carat.Problem()
    v = p.add_euclidean(np.zeros(2))
    with pytest.raises(TypeError, match="not callable"):
        p.add_rows(3, [v], rows=4)
    with pytest.raises(ValueError, match="rows=5 is not a whole number of groups of group=2"):
        p.add_rows(lambda mc, rows: mc, [v], rows=5, group=2)
    with pytest.raises(ValueError, match=r"rows: must be an integer in \[-2147483648, 2147483647\]"):
        p.add_rows(lambda mc, rows: mc, [v], rows=2**40)
    with pytest.raises(ValueError, match="add_rows argument 1: variable 7 does not exist"):
        p.add_rows(lambda mc, rows: mc, [7], rows=4)
    with pytest.raises(ValueError, match="add_rows: .*'tukey'"):
        p.add_rows(lambda mc, rows: mc, [v], rows=4, loss="tukey")
    with pytest.raises(TypeError, match="unexpected keyword argument 'max_iteration'"):
        carat.solve(p, max_iteration=3)
    with pytest.raises(ValueError, match="unknown LM start 'newton'"):
        carat.solve(p, lm_start="newton")


@pytest.mark.parametrize("slots", [2, 3])
def test_groups_over_the_same_variables_form_one_block_in_order_of_first_use(slots):
    # Row g: sum_j (j + 1) x_{tuple_g[j]} - g, one group per row.
    tuples = np.array([[0, 1, 2], [1, 0, 2], [0, 1, 2], [0, 2, 1], [1, 0, 2], [3, 1, 0],
                       [0, 2, 1]])[:, :slots]
    p = carat.Problem()
    start = np.array([0.5, -1.0, 2.0, 0.25])
    ids = [p.add_euclidean(np.array([x])) for x in start]
    weights = np.arange(1.0, slots + 1.0)

    def residual(*arguments):
        values, rows = arguments[:-1], arguments[-1]
        r = sum(w * v[:, 0] for w, v in zip(weights, values)) - rows
        return r, [np.full((len(rows), 1), w) for w in weights]

    added = p.add_rows(residual, [np.array(ids)[tuples[:, j]] for j in range(slots)],
                       rows=len(tuples))
    distinct = list(dict.fromkeys(map(tuple, tuples)))  # in order of first use
    assert p.num_residual_blocks == len(distinct)
    assert list(added) == list(range(len(distinct)))
    r = start[tuples] @ weights - np.arange(len(tuples))
    assert p.cost() == pytest.approx(0.5 * r @ r, rel=1e-14)
    gradient = np.zeros(len(start))
    for g, t in enumerate(tuples):
        gradient[t] += weights * r[g]
    np.testing.assert_allclose(p.gradient(), gradient, rtol=1e-14, atol=1e-14)
    twice = tuples.copy()
    twice[4, 1] = twice[4, 0]
    with pytest.raises(ValueError, match="add_rows: arguments 1 and 2 are the same variable "
                                         r"\(1\) in group 4; a block's variables must be distinct"):
        p.add_rows(residual, [np.array(ids)[twice[:, j]] for j in range(slots)], rows=len(tuples))


def test_ctrl_c_in_a_slow_residual_ends_the_solve():
    script = textwrap.dedent(
        """
        import os, signal, threading, time
        import numpy as np
        import carat
        def slow(mc, rows):
            time.sleep(0.05)
            return np.full(len(rows), np.exp(-mc[0]))  # its minimum lies at infinity
        p = carat.Problem()
        v = p.add_euclidean(np.zeros(1))
        p.add_rows(slow, [v], rows=10)
        threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        start = time.monotonic()
        try:
            carat.solve(p, max_iterations=100000, function_tolerance=0, gradient_tolerance=0,
                        parameter_tolerance=0)
            print("finished")
        except KeyboardInterrupt:
            print("interrupted after %.1f s" % (time.monotonic() - start))
        print("usable", p.cost() > 0.0)
        """
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         env=dict(os.environ), timeout=120)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.split("\n")
    assert lines[0].startswith("interrupted after"), run.stdout
    assert float(lines[0].split()[2]) < 5.0
    assert lines[1] == "usable True"
