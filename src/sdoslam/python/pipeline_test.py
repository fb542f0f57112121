"""sdoslam.Pipeline and sdoslam.Dataset: tracking NumPy frames, and what bad input raises."""

import subprocess

import numpy as np
import pytest

import sdoslam


def track_all(pipeline, dataset):
    return [pipeline.track(bgr, depth, t) for bgr, depth, t in dataset]


def test_sequential_pipeline_gives_the_trajectory_of_run_sequential(
        fr2_desk, fr2_config, executable, tmp_path):
    out = tmp_path / "run"
    subprocess.run([str(executable), "run", "--dataset", str(fr2_desk), "--config",
                    str(fr2_config), "--mode", "sdo", "--sequential", "--out", str(out)],
                   check=True, capture_output=True)
    expected = np.loadtxt(out / "CameraTrajectory.txt")

    pipeline = sdoslam.Pipeline(fr2_config, mode="sdo", sequential=True)
    results = track_all(pipeline, sdoslam.Dataset(fr2_desk, fr2_config))
    got = pipeline.trajectory()

    assert got.shape == expected.shape
    # The file has timestamps to the microsecond, positions and quaternions to 1e-9.
    np.testing.assert_allclose(got[:, 0], expected[:, 0], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got[:, 1:4], expected[:, 1:4], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got[:, 4:], expected[:, 4:], rtol=0, atol=1e-6)
    # The frames with a pose are the trajectory's.
    tracked = [r["timestamp"] for r in results if r["pose"] is not None]
    np.testing.assert_allclose(tracked, expected[:, 0], rtol=0, atol=1e-6)


def test_threaded_pipeline_tracks_and_maps(fr2_desk, fr2_config):
    dataset = sdoslam.Dataset(fr2_desk, fr2_config)
    with sdoslam.Pipeline(fr2_config) as pipeline:  # sdo, mapping in a thread of its own
        assert pipeline.mode == "sdo" and not pipeline.sequential
        results = track_all(pipeline, dataset)
    assert pipeline.frames == len(dataset) == 50
    last = results[-1]
    assert last["state"] == "ok" and last["keyframes"] >= 1
    assert last["pose"].shape == (4, 4) and last["pose"].dtype == np.float64
    np.testing.assert_allclose(last["pose"][3], [0, 0, 0, 1])
    assert last["labels"].shape == (480, 640) and last["labels"].dtype == np.uint8
    assert set(np.unique(last["labels"])) <= {0, 1, 2, 3}
    assert pipeline.trajectory().shape == (50, 8)
    points = pipeline.map_points()
    assert points.ndim == 2 and points.shape[1] == 3 and points.shape[0] > 0
    assert points.dtype == np.float64 and np.isfinite(points).all()
    with pytest.raises(sdoslam.Error, match="shut down"):
        pipeline.track(*dataset[0])


def test_map_points_after_tracking_a_synthetic_sequence(static_room):
    folder, _ = static_room
    config = folder / "camera.yaml"
    pipeline = sdoslam.Pipeline(config, mode="conventional", sequential=True)
    results = track_all(pipeline, sdoslam.Dataset(folder, config))
    assert results[0]["state"] == "ok" and results[0]["keyframe"]
    assert all(r["pose"] is not None for r in results)
    # Conventional mode has no front end: every pixel is static.
    assert not results[-1]["labels"].any()
    points = pipeline.map_points()
    assert points.shape[1] == 3 and points.shape[0] > 0
    assert len(pipeline.map_points(min_observations=1)) >= len(points)


def test_dataset_reads_frames_as_the_runner_does(fr2_desk, fr2_config):
    dataset = sdoslam.Dataset(fr2_desk, fr2_config)
    assert len(dataset) == 50 and dataset.layout == "tum"
    bgr, depth, timestamp = dataset[0]
    assert bgr.shape == (480, 640, 3) and bgr.dtype == np.uint8
    assert depth.shape == (480, 640) and depth.dtype == np.float32
    assert timestamp == dataset.timestamps[0]
    # configs/tum_fr2.yaml: 5208 raw units a metre, nothing outside 0.1..10 m.
    valid = depth[depth > 0]
    assert valid.min() >= 0.1 and valid.max() <= 10.0
    assert dataset[-1][2] == dataset.timestamps[49]
    assert dataset.ground_truth.shape[1] == 8
    with pytest.raises(IndexError):
        dataset[50]


@pytest.fixture(scope="module")
def pipeline(fr2_config):
    return sdoslam.Pipeline(fr2_config, mode="conventional", sequential=True)


def frame(bgr_dtype=np.uint8, depth_dtype=np.float32, shape=(480, 640)):
    return np.zeros(shape + (3,), bgr_dtype), np.ones(shape, depth_dtype)


@pytest.mark.parametrize("bgr, depth, message", [
    (*frame(bgr_dtype=np.float32), "bgr: expected uint8 of shape \\(480, 640, 3\\)"),
    (np.zeros((480, 640), np.uint8), frame()[1], "bgr: .* got uint8 of shape \\(480, 640\\)"),
    (*frame(shape=(240, 320)), "bgr: .*the camera config's 640x480"),
    (frame()[0], np.ones((480, 640), np.uint16), "depth_m: .*raw sensor units"),
    (frame()[0], np.ones((480, 640), np.float64), "depth_m: .*astype"),
    (frame()[0], np.ones((480, 640, 1), np.float32), "depth_m: expected float32 metres"),
    ([[0]], frame()[1], "bgr: expected a NumPy array, got <class 'list'>"),
])
def test_bad_arrays_raise_value_error(pipeline, bgr, depth, message):
    frames = pipeline.frames
    with pytest.raises(ValueError, match=message):
        pipeline.track(bgr, depth, 0.0)
    assert pipeline.frames == frames


def test_bad_mask_and_timestamp_raise_value_error(pipeline):
    bgr, depth = frame()
    with pytest.raises(ValueError, match="dynamic_mask"):
        pipeline.track(bgr, depth, 0.0, dynamic_mask=np.zeros((480, 640), np.float32))
    with pytest.raises(ValueError, match="timestamp"):
        pipeline.track(bgr, depth, float("nan"))


def test_strided_views_are_tracked_as_copies(pipeline):
    bgr, depth = frame()
    wide = np.zeros((480, 1280, 3), np.uint8)
    frames = pipeline.frames
    result = pipeline.track(wide[:, ::2], depth.T.copy().T, 0.0)
    assert result["state"] == "not_initialized" and result["pose"] is None
    assert result["index"] == frames and pipeline.frames == frames + 1


def test_missing_config_raises_error_naming_the_file(tmp_path):
    missing = tmp_path / "no_such_config.yaml"
    with pytest.raises(sdoslam.Error, match="no_such_config.yaml") as raised:
        sdoslam.Pipeline(missing)
    assert isinstance(raised.value, RuntimeError)


def test_unknown_mode_raises_error_naming_the_known_ones(fr2_config):
    with pytest.raises(sdoslam.Error, match="unknown mode 'foo' \\(known: conventional, sdo"):
        sdoslam.Pipeline(fr2_config, mode="foo")


def test_bad_config_key_raises_error_naming_file_and_key(fr2_config, tmp_path):
    config = tmp_path / "bad.yaml"
    config.write_text(fr2_config.read_text() + "tracking:\n  no_such_key: 1\n")
    with pytest.raises(sdoslam.Error, match="bad.yaml.*no_such_key"):
        sdoslam.Pipeline(config)


def test_missing_dataset_raises_error(fr2_config, tmp_path):
    with pytest.raises(sdoslam.Error, match="nowhere"):
        sdoslam.Dataset(tmp_path / "nowhere", fr2_config)
