"""carat.solve_g2o on pose graphs written here."""

import numpy as np
import pytest

import carat
from conftest import se3_exp


def quaternion(R):
    w = np.sqrt(max(0.0, 1 + np.trace(R))) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    return x, y, z, w


def pose_text(T):
    return " ".join(f"{v:.17g}" for v in (*T[:3, 3], *quaternion(T[:3, :3])))


def ring_graph_3d(path, n=40, seed=0):
    rng = np.random.default_rng(seed)
    truth = [se3_exp([0, 0, 2 * np.pi * k / n], [10 * np.cos(2 * np.pi * k / n), 10 * np.sin(2 * np.pi * k / n), 0]) for k in range(n)]
    info = " ".join(["100 0 0 0 0 0", "100 0 0 0 0", "100 0 0 0", "400 0 0", "400 0", "400"])
    lines = []
    estimate = truth[0]
    for k in range(n):
        if k:
            measured = np.linalg.inv(truth[k - 1]) @ truth[k] @ se3_exp(rng.normal(scale=0.01, size=3), rng.normal(scale=0.05, size=3))
            estimate = estimate @ measured
        lines.append(f"VERTEX_SE3:QUAT {k} {pose_text(estimate)}")
    for k in range(n):
        j = (k + 1) % n
        measured = np.linalg.inv(truth[k]) @ truth[j] @ se3_exp(rng.normal(scale=0.005, size=3), rng.normal(scale=0.02, size=3))
        lines.append(f"EDGE_SE3:QUAT {k} {j} {pose_text(measured)} {info}")
    path.write_text("\n".join(lines) + "\n")


def test_solves_a_3d_graph(tmp_path):
    path = tmp_path / "ring.g2o"
    ring_graph_3d(path)
    result = carat.solve_g2o(path)
    assert result["termination"] == "CONVERGENCE"
    assert result["final_cost"] < 1e-3 * result["initial_cost"]
    assert result["iterations"] >= 1 and result["time_s"] > 0
    assert (result["vertices"], result["edges"], result["dimension"]) == (40, 40, 3)
    out = tmp_path / "solved.g2o"
    again = carat.solve_g2o(path, out=out, loss="cauchy", loss_scale=2.0, threads=2)
    assert again["output"] == str(out) and out.stat().st_size > 0
    resolved = carat.solve_g2o(out, loss="cauchy", loss_scale=2.0)
    assert resolved["initial_cost"] == pytest.approx(again["final_cost"], rel=1e-6)


def test_solves_a_2d_graph(tmp_path):
    n = 30
    rng = np.random.default_rng(1)
    lines = [f"VERTEX_SE2 {k} {k + rng.normal(scale=0.3)} {rng.normal(scale=0.3)} {rng.normal(scale=0.05)}" for k in range(n)]
    lines += [f"EDGE_SE2 {k} {k + 1} 1 0 0 100 0 0 100 0 400" for k in range(n - 1)]
    (tmp_path / "line.g2o").write_text("\n".join(lines) + "\n")
    result = carat.solve_g2o(tmp_path / "line.g2o")
    assert result["dimension"] == 2 and result["termination"] == "CONVERGENCE"
    assert result["final_cost"] < 1e-9 * result["initial_cost"]


def test_bad_graphs_raise(tmp_path):
    with pytest.raises(carat.Error, match="missing.g2o"):
        carat.solve_g2o(tmp_path / "missing.g2o")
    (tmp_path / "cut.g2o").write_text("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 0 0\n")
    with pytest.raises(carat.Error, match="cut.g2o:2"):
        carat.solve_g2o(tmp_path / "cut.g2o")
    path = tmp_path / "ring.g2o"
    ring_graph_3d(path, n=5)
    with pytest.raises(carat.Error, match="'lm' or|lm"):
        carat.solve_g2o(path, method="newton")
    with pytest.raises(carat.Error, match="overwrite the input"):
        carat.solve_g2o(path, out=path)


def test_covariance_of_a_2d_chain(tmp_path):
    # Unit steps along x from vertex 0 (held constant), exact measurements, information
    # diag(100, 100, 400) in (x, y, theta). A chain is a tree: at the solution the covariance of
    # vertex k is the propagation of the k step covariances, in carat's tangent [omega, vx, vy]:
    # sum over d = 0 .. k - 1 of A_d diag(1/400, 1/100, 1/100) A_d^T with A_d the adjoint of a
    # step of d metres back (omega moves vy by d omega).
    n = 6
    lines = [f"VERTEX_SE2 {k} {k + 0.1 * np.sin(k)} {0.05 * k} {0.02 * k}" for k in range(n)]
    lines += [f"EDGE_SE2 {k} {k + 1} 1 0 0 100 0 0 100 0 400" for k in range(n - 1)]
    (tmp_path / "chain.g2o").write_text("\n".join(lines) + "\n")
    result = carat.solve_g2o(tmp_path / "chain.g2o", covariance=True)
    assert result["final_cost"] < 1e-16
    assert list(result["covariance_ids"]) == [1, 2, 3, 4, 5]
    assert result["covariance"].shape == (5, 3, 3) and result["covariance_s"] >= 0
    step = np.diag([1 / 400, 1 / 100, 1 / 100])
    for k in range(1, n):
        expected = np.zeros((3, 3))
        for d in range(k):
            A = np.eye(3)
            A[2, 0] = d
            expected += A @ step @ A.T
        np.testing.assert_allclose(result["covariance"][k - 1], expected, rtol=1e-9, atol=1e-12)


def test_covariance_gauge_is_checked(tmp_path):
    path = tmp_path / "line.g2o"
    path.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n")
    with pytest.raises(carat.Error, match="unknown covariance gauge 'none' \\(valid: error, pseudo-inverse\\)"):
        carat.solve_g2o(path, covariance=True, covariance_gauge="none")
    result = carat.solve_g2o(path, covariance=True, covariance_gauge="pseudo-inverse")
    np.testing.assert_allclose(result["covariance"][0], np.eye(3), rtol=1e-12)


def test_blas_kernels_suggest_only_for_openblas_fallback():
    k = carat.blas_kernels()
    assert set(k) == {"library", "core", "suggested_core"}
    if k["library"] == "":
        assert k["core"] == "" and k["suggested_core"] == ""
        return
    assert k["library"] == "OpenBLAS" and k["core"] != ""
    assert k["suggested_core"] in ("", "Haswell", "SkylakeX")
    if k["suggested_core"]:
        assert k["core"].lower() == "prescott"
