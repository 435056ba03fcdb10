"""carat.align, a pair's GICP factor and its lossless rows."""

import numpy as np
import pytest

import carat
from conftest import rotation_angle_deg, se3_exp


def transform(T, points):
    return (points.astype(np.float64) @ T[:3, :3].T + T[:3, 3]).astype(np.float32)


@pytest.fixture(scope="module")
def scans():
    scans, _ = carat.simulate_scans(frames=8, laps=1)
    return scans


def test_align_recovers_a_known_motion(scans):
    target = scans[0]
    T_true = se3_exp(np.radians([0.5, -0.8, 4.0]), [0.6, -0.3, 0.05])
    source = transform(np.linalg.inv(T_true), target)  # source seen from T_true
    result = carat.align(target, source, threads=2)
    assert result.converged and result.constrained_dof == 6
    dT = np.linalg.inv(T_true) @ result.T_target_source
    assert np.linalg.norm(dT[:3, 3]) < 0.01
    assert rotation_angle_deg(dT[:3, :3]) < 0.05
    assert result.H.shape == (6, 6) and np.all(np.linalg.eigvalsh(result.H) > 0)
    # From frames and an initial guess: the same answer.
    again = carat.align(carat.Frame(target), carat.Frame(source), T_init=np.eye(4))
    assert np.abs(again.T_target_source - result.T_target_source).max() < 1e-6


def test_align_methods_and_bad_arguments(scans):
    target, source = scans[0], scans[1]
    for method in ("point-to-plane", "point-to-point"):
        assert carat.align(target, source, method=method).iterations >= 1
    with pytest.raises(carat.Error, match="gicp"):
        carat.align(target, source, method="icp")
    with pytest.raises(ValueError, match="T_init: expected a 4 x 4 pose"):
        carat.align(target, source, T_init=np.eye(3))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match="T_init: the rotation block is not a rotation"):
        carat.align(target, source, T_init=bad)
    nan = np.eye(4)
    nan[0, 3] = np.nan
    with pytest.raises(ValueError, match="T_init: the pose is not finite"):
        carat.align(target, source, T_init=nan)
    with pytest.raises(carat.Error, match=r"align: max_correspondence_distance must be finite and > 0 \(metres\), got -1"):
        carat.align(target, source, max_correspondence_distance=-1)
    with pytest.raises(ValueError, match="threads: must be >= 1, got -2"):
        carat.align(target, source, threads=-2)
    with pytest.raises(ValueError, match="source: point 3 is not finite"):
        broken = source.copy()
        broken[3, 1] = np.inf
        carat.align(target, broken)


def test_align_on_the_real_kitti_pair(data_dir):
    pair = data_dir / "kitti00_pair"
    if not (pair / "000000.bin").exists():
        pytest.skip("kitti00_pair absent")
    target = carat.read_point_cloud(pair / "000000.bin", kitti_format="xyz")
    source = carat.read_point_cloud(pair / "000001.bin", kitti_format="xyz")
    result = carat.align(target, source, voxel_size=0.25, threads=2)
    assert result.converged and result.constrained_dof == 6
    # small_gicp at the same settings: t ~= (0.690, 0.004, 0.007) m, rotation ~0.2 deg.
    assert np.linalg.norm(result.T_target_source[:3, 3] - [0.690, 0.004, 0.007]) < 0.01
    assert abs(rotation_angle_deg(result.T_target_source[:3, :3]) - 0.2) < 0.1


def test_align_on_the_real_small_gicp_pair(data_dir):
    pair = data_dir / "smallgicp_pair"
    if not (pair / "target.ply").exists():
        pytest.skip("smallgicp_pair absent")
    target = carat.read_point_cloud(pair / "target.ply")
    source = carat.read_point_cloud(pair / "source.ply")
    reference = np.loadtxt(pair / "T_target_source.txt")
    result = carat.align(target, source, threads=2)
    assert result.converged
    dT = np.linalg.inv(reference) @ result.T_target_source
    assert np.linalg.norm(dT[:3, 3]) < 0.02
    assert rotation_angle_deg(dT[:3, :3]) < 0.5


def test_lossless_rows_keep_the_cost_at_every_pose(scans):
    target, source = carat.Frame(scans[0]), carat.Frame(scans[1])
    T = carat.align(target, source).T_target_source
    factor = carat.GicpFactor(target, source, T)
    assert factor.num_rows == 3 * factor.num_correspondences > 1000
    lossless = factor.lossless()
    assert lossless.num_rows <= 13 and lossless.original_rows == factor.num_rows
    rng = np.random.default_rng(0)
    for _ in range(5):
        T_other = T @ se3_exp(rng.normal(scale=0.05, size=3), rng.normal(scale=0.3, size=3))
        full = factor.cost(T_other)
        assert abs(lossless.cost(T_other) - full) <= 1e-9 * full
        e, J = factor.evaluate(T_other)
        el, Jl = lossless.evaluate(T_other)
        np.testing.assert_allclose(Jl.T @ Jl, J.T @ J, rtol=0, atol=1e-8 * np.abs(J.T @ J).max())
        np.testing.assert_allclose(Jl.T @ el, J.T @ e, rtol=0, atol=1e-8 * np.abs(J.T @ J).max())
        assert abs(e @ e - full) <= 1e-12 * full


def test_coreset_of_a_factor_is_exact_at_its_point(scans):
    target, source = carat.Frame(scans[0]), carat.Frame(scans[1])
    T = carat.align(target, source).T_target_source
    factor = carat.GicpFactor(target, source, T)
    e, J = factor.evaluate(T)
    assert J.shape == (factor.num_rows, 6)
    idx, w = carat.coreset(J, e)
    assert len(idx) == 29
    H = J.T @ J
    np.testing.assert_allclose((J[idx].T * w) @ J[idx], H, rtol=0, atol=1e-11 * np.abs(H).max())
    np.testing.assert_allclose((J[idx].T * w) @ e[idx], J.T @ e, rtol=0, atol=1e-11 * np.abs(H).max())
    assert abs(w @ e[idx] ** 2 - e @ e) <= 1e-11 * (e @ e)
    far = np.eye(4)
    far[0, 3] = 1e4
    with pytest.raises(carat.Error, match="GicpFactor: no source point has a target point within 1 m"):
        carat.GicpFactor(target, source, far)
    with pytest.raises(TypeError):
        carat.GicpFactor(target, None, T)
    with pytest.raises(ValueError, match="max_correspondence_distance: must be finite and > 0"):
        carat.GicpFactor(target, source, T, max_correspondence_distance=float("inf"))
