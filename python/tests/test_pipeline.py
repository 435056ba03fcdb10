"""The dense global-registration pipeline from Python, on a small synthetic world."""

import numpy as np
import pytest

import carat


def test_simulation_is_complete(small_drive):
    s = small_drive
    assert s.truth.shape == s.initial.shape == s.drift.shape == (24, 4, 4)
    assert len(s.frames) == 24 and all(isinstance(f, carat.Frame) for f in s.frames)
    pairs = s.graph.pairs
    assert pairs.shape == (len(s.graph), 2) and np.all(pairs[:, 0] < pairs[:, 1])
    assert {(i, i + 1) for i in range(23)} <= {tuple(p) for p in pairs}
    assert np.all(s.graph.overlaps[: len(pairs)] >= 0)
    # Two laps: frames k and k + 12 sit at the same place, and the graph links them.
    assert any(j - i == 12 for i, j in pairs)
    again = carat.dense_graph(s.frames, s.initial, threads=1)
    assert np.array_equal(again.pairs, pairs)


@pytest.fixture(scope="module")
def solved(small_drive):
    s = small_drive
    return {m: carat.optimize(s.frames, s.graph, s.initial, sampling=m, threads=2) for m in ("full", "exact", "lossless", "random")}


def test_optimize_every_sampling(small_drive, solved):
    s = small_drive
    initial = carat.ate(s.initial, s.truth)["rmse"]
    for method, result in solved.items():
        assert result.poses.shape == (24, 4, 4)
        assert result.summary["termination"] in ("CONVERGENCE", "NO_CONVERGENCE"), method
        assert result.summary["final_cost"] < result.summary["initial_cost"]
        np.testing.assert_allclose(result.poses[0], s.initial[0], rtol=0, atol=1e-12)  # held
        assert result.stats["factors"] == len(s.graph) == len(result.factor_costs)
    for method in ("full", "exact", "lossless"):
        ate = carat.ate(solved[method].poses, s.truth)["rmse"]
        assert ate < 0.5 * initial, (method, ate, initial)
    full, lossless, exact = solved["full"], solved["lossless"], solved["exact"]
    # Lossless rows have the full factors' cost function: the same optimum.
    assert abs(lossless.summary["final_cost"] / full.summary["final_cost"] - 1) < 1e-6
    assert np.abs(lossless.poses[:, :3, 3] - full.poses[:, :3, 3]).max() < 1e-4
    # Exact coresets: 29 rows per factor, far less memory than the full factors.
    assert exact.stats["rows"] == 29 * len(s.graph)
    assert exact.stats["residual_bytes"] < 0.05 * full.stats["residual_bytes"]


def test_pose_graph_baselines(small_drive, solved):
    s = small_drive
    for information in ("hessian", "identity"):
        result = carat.pose_graph(s.frames, s.graph, s.initial, information=information, threads=2)
        assert result.poses.shape == (24, 4, 4)
        assert result.summary["termination"] != "FAILURE"
        assert result.stats["factors"] == len(s.graph)
    hessian = carat.pose_graph(s.frames, s.graph.pairs, s.initial, threads=2)
    assert carat.ate(hessian.poses, s.truth)["rmse"] < carat.ate(s.initial, s.truth)["rmse"]


def test_frames_from_a_folder_and_from_arrays(tmp_path):
    scans, truth = carat.simulate_scans(frames=6, laps=1)
    for k, scan in enumerate(scans):
        carat.write_point_cloud(tmp_path / f"{k:06d}.bin", scan)
    carat.write_trajectory(tmp_path / "poses.txt", truth)
    from_folder = carat.load_frames(tmp_path, voxel_size=0.5, threads=2)
    from_arrays = carat.preprocess_frames(scans, voxel_size=0.5, threads=2)
    assert len(from_folder) == len(from_arrays) == 6
    for a, b in zip(from_folder, from_arrays):
        assert np.array_equal(a.points, b.points)
    assert from_folder[2].name.endswith("000002.bin")
    poses = carat.read_trajectory(tmp_path / "poses.txt")
    np.testing.assert_allclose(poses, truth, rtol=0, atol=1e-12)
    graph = carat.dense_graph(from_folder, poses)
    result = carat.optimize(from_folder, graph, poses, sampling="lossless")
    assert carat.ate(result.poses, truth)["rmse"] < 0.05


def test_ate_matches_numpy(small_drive):
    s = small_drive
    T = np.eye(4)
    T[:3, :3] = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    T[:3, 3] = [5, -2, 1]
    moved = T @ s.truth
    assert carat.ate(moved, s.truth)["rmse"] < 1e-9
    stats = carat.ate(s.initial, s.truth, align=False)
    errors = np.linalg.norm(s.initial[:, :3, 3] - s.truth[:, :3, 3], axis=1)
    assert stats["rmse"] == pytest.approx(np.sqrt(np.mean(errors**2)), rel=1e-12)
    assert stats["max"] == pytest.approx(errors.max(), rel=1e-12)
    assert stats["num_poses"] == 24


def test_mapping_arguments_are_checked(small_drive):
    s = small_drive
    with pytest.raises(ValueError, match="poses: 5 poses for 24 frames"):
        carat.optimize(s.frames, s.graph, s.initial[:5])
    with pytest.raises(ValueError, match=r"pairs\[0\]: frame indices must be integers in \[0, 24\)"):
        carat.optimize(s.frames, np.array([[0, 30]]), s.initial)
    with pytest.raises(ValueError, match=r"pairs\[0\]: the target index must be below"):
        carat.optimize(s.frames, np.array([[3, 1]]), s.initial)
    with pytest.raises(TypeError, match=r"frames\[1\]: expected a carat.Frame, got ndarray"):
        carat.optimize([s.frames[0], np.zeros((3, 3))], np.array([[0, 1]]), s.initial[:2])
    with pytest.raises(carat.Error, match="full, exact, random, lossless|'full'"):
        carat.optimize(s.frames, s.graph, s.initial, sampling="everything")
    with pytest.raises(carat.Error, match="cauchy_scale must be finite and >= 0"):
        carat.pose_graph(s.frames, s.graph, s.initial, cauchy_scale=float("nan"))
    with pytest.raises(ValueError, match="read-only"):
        s.truth[0, 0, 0] = 5.0
    with pytest.raises(carat.Error, match="3 poses"):
        carat.ate(s.truth[:3], s.truth)


def test_loops_close_a_drifting_drive_and_odometry_follows_a_lap():
    s = carat.simulate(frames=40, laps=2, drift_heading_deg=0.1, drift_translation=0.005, drift_rotation_deg=0.02, odometry=False, dense_graph=False, threads=2)
    closed = carat.close_loops(s.frames, s.drift, threads=2)
    assert len(closed["loops"]) >= 15
    for c in closed["candidates"]:
        if c["verdict"] != "accepted":
            continue
        truth = np.linalg.inv(s.truth[c["target"]]) @ s.truth[c["source"]]
        assert np.linalg.norm(truth[:3, 3] - c["T_target_source"][:3, 3]) < 0.2
    assert carat.ate(s.drift, s.truth)["rmse"] > 2.0
    assert carat.ate(closed["poses"], s.truth)["rmse"] < 0.5
    assert closed["summary"]["termination"] != "FAILURE"

    lap = carat.simulate(frames=50, laps=1, odometry=False, dense_graph=False, threads=2)
    poses = carat.odometry(lap.frames, threads=2)
    assert poses.shape == (50, 4, 4)
    assert carat.ate(poses, lap.truth)["rmse"] < 0.2
    with pytest.raises(ValueError, match="poses: 3 poses for 40 frames"):
        carat.close_loops(s.frames, s.drift[:3])
