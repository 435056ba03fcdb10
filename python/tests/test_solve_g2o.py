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
