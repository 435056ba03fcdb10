"""Point-cloud files, voxel downsampling, covariances and carat.Frame from numpy."""

import gc
import os

import numpy as np
import pytest

import carat


@pytest.fixture()
def cloud():
    rng = np.random.default_rng(0)
    return rng.uniform(-20, 20, size=(5000, 3)).astype(np.float32)


@pytest.mark.parametrize("name,ascii", [("c.pcd", False), ("c.pcd", True), ("c.ply", False), ("c.ply", True), ("c.bin", False)])
def test_files_round_trip(tmp_path, cloud, name, ascii):
    path = tmp_path / name
    carat.write_point_cloud(path, cloud, ascii=ascii)
    back = carat.read_point_cloud(path)
    assert back.dtype == np.float32 and back.shape == cloud.shape
    if ascii:
        np.testing.assert_allclose(back, cloud, rtol=1e-6, atol=1e-5)
    else:
        assert np.array_equal(back, cloud)


def test_kitti_layouts(tmp_path, cloud):
    carat.write_point_cloud(tmp_path / "xyz.bin", cloud, kitti_format="xyz")
    assert os.path.getsize(tmp_path / "xyz.bin") == 12 * len(cloud)
    assert np.array_equal(carat.read_point_cloud(tmp_path / "xyz.bin", kitti_format="xyz"), cloud)
    xyzi = np.hstack([cloud, np.ones((len(cloud), 1), np.float32)])
    (tmp_path / "raw.bin").write_bytes(xyzi.tobytes())
    assert np.array_equal(carat.read_point_cloud(str(tmp_path / "raw.bin")), cloud)


def test_bad_files_name_the_file(tmp_path):
    (tmp_path / "empty.pcd").write_bytes(b"")
    with pytest.raises(carat.Error, match="empty.pcd"):
        carat.read_point_cloud(tmp_path / "empty.pcd")
    (tmp_path / "cut.bin").write_bytes(b"\0" * 18)
    with pytest.raises(carat.Error, match="cut.bin"):
        carat.read_point_cloud(tmp_path / "cut.bin")
    with pytest.raises(carat.Error, match="unsupported file type '.txt'"):
        carat.read_point_cloud(tmp_path / "points.txt")
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(carat.Error, match="dir.ply"):
        carat.read_point_cloud(tmp_path / "dir.ply")
    nan = np.array([[0, 0, 0], [1, np.nan, 2]], np.float32)
    (tmp_path / "nan.bin").write_bytes(nan.tobytes())
    with pytest.raises(carat.Error, match="nan.bin"):
        carat.read_point_cloud(tmp_path / "nan.bin", kitti_format="xyz")
    kept = carat.read_point_cloud(tmp_path / "nan.bin", kitti_format="xyz", drop_non_finite=True)
    assert kept.shape == (1, 3)
    with pytest.raises(ValueError, match="point 1 is not finite"):
        carat.write_point_cloud(tmp_path / "out.pcd", nan)
    assert not (tmp_path / "out.pcd").exists()


def test_voxel_downsample_is_the_centroid_per_voxel(cloud):
    size = 4.0
    down = carat.voxel_downsample(cloud, size)
    keys = np.floor(cloud.astype(np.float64) / size).astype(np.int64)
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    expected = np.zeros((inverse.max() + 1, 3))
    np.add.at(expected, inverse, cloud.astype(np.float64))
    expected /= np.bincount(inverse)[:, None]
    assert down.shape == expected.shape
    order = lambda a: a[np.lexsort(a.T[::-1])]
    np.testing.assert_allclose(order(down.astype(np.float64)), order(expected), atol=1e-4)
    with pytest.raises(carat.Error, match="voxel"):
        carat.voxel_downsample(cloud, 0.0)


def test_covariances_of_a_plane():
    rng = np.random.default_rng(1)
    plane = np.column_stack([rng.uniform(-5, 5, 2000), rng.uniform(-5, 5, 2000), np.zeros(2000)])
    C = carat.estimate_covariances(plane, neighbors=10)
    assert C.shape == (2000, 3, 3)
    assert np.allclose(C, np.transpose(C, (0, 2, 1)))
    eig = np.linalg.eigvalsh(C)
    np.testing.assert_allclose(eig[:, 0], 1e-3, rtol=1e-3)
    np.testing.assert_allclose(eig[:, 1:], 1.0, rtol=1e-3)
    normals = np.linalg.eigh(C)[1][:, :, 0]
    assert np.all(np.abs(normals[:, 2]) > 0.999)


def test_frame_views_its_points(cloud):
    frame = carat.Frame(cloud, voxel_size=2.0, name="f")
    points = frame.points
    assert points.dtype == np.float32 and points.shape == (len(frame), 3)
    assert not points.flags.writeable
    with pytest.raises(ValueError):
        points[0, 0] = 1.0
    np.testing.assert_array_equal(points, carat.voxel_downsample(cloud, 2.0))
    assert frame.covariances.shape == (len(frame), 3, 3)
    assert frame.name == "f" and frame.constrained_dof == 6
    copy = np.array(points)
    del frame
    gc.collect()
    np.testing.assert_array_equal(points, copy)  # the view keeps its frame alive


def test_point_arrays_are_checked(cloud):
    with pytest.raises(ValueError, match=r"points: expected an N x 3 array of points, got shape \(5000, 2\)"):
        carat.voxel_downsample(cloud[:, :2], 1.0)
    with pytest.raises(TypeError, match="points: expected an array of real numbers, got dtype <U1"):
        carat.voxel_downsample([["a", "b", "c"]], 1.0)
    huge = np.array([[1e300, 0.0, 0.0]])
    with pytest.raises(ValueError, match="point 0 is not finite"):
        carat.voxel_downsample(huge, 1.0)
    xyzi = np.hstack([cloud, np.zeros((len(cloud), 1), np.float32)])
    assert np.array_equal(carat.voxel_downsample(xyzi[::1], 3.0), carat.voxel_downsample(cloud, 3.0))
    assert np.array_equal(carat.voxel_downsample(cloud.astype(np.float64)[::-1], 3.0).shape, carat.voxel_downsample(cloud, 3.0).shape)
    with pytest.raises(ValueError, match=r"neighbors: must be in \[4, 1000\], got 100000"):
        carat.Frame(cloud, neighbors=100000)
    with pytest.raises(ValueError, match="threads: must be >= 1, got 0"):
        carat.Frame(cloud, threads=0)
    with pytest.raises(carat.Error, match="points: only 10 points after downsampling"):
        carat.Frame(cloud[:10], voxel_size=0.1)
