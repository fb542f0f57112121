"""sdoslam.run, sdoslam.evaluate and sdoslam.synth: the commands of the same name, as calls."""

import json
import subprocess

import numpy as np
import pytest

import sdoslam


def quaternion_product(a, b):
    """Hamilton product of quaternions stored x y z w (rows broadcast)."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def rotation_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def helix(poses=120):
    """TUM rows of a camera on a helix at 30 Hz, turning as it goes; positions come in equal
    pairs (frames 2k and 2k+1 at one place), which test_evaluate_known_noise relies on."""
    t = 1000.0 + np.arange(poses) / 30.0
    s = np.repeat(np.arange(poses // 2), 2) * 0.1
    positions = np.stack([np.cos(s), np.sin(s), 0.05 * s], axis=1)
    half = 0.02 * np.arange(poses)
    quaternions = np.stack([np.zeros(poses), 0.3 * np.sin(half), np.sin(half),
                            np.cos(half)], axis=1)
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    return np.column_stack([t, positions, quaternions])


def test_evaluate_a_rigidly_moved_copy_is_zero():
    gt = helix()
    q = np.array([0.1, -0.2, 0.3, 0.9])
    q /= np.linalg.norm(q)
    est = gt.copy()
    est[:, 1:4] = gt[:, 1:4] @ rotation_matrix(q).T + [2.0, -1.0, 0.5]
    est[:, 4:] = quaternion_product(q, gt[:, 4:])
    result = sdoslam.evaluate(gt, est)
    assert result["matched_poses"] == 120
    assert result["ate"]["rmse"] < 1e-9
    assert result["rte"]["translation"]["rmse"] < 1e-9
    assert result["rte"]["rotation_deg"]["rmse"] < 1e-6
    np.testing.assert_allclose(result["alignment"]["rotation"], rotation_matrix(q).T, atol=1e-9)


def test_evaluate_known_noise():
    # Each pair of equal ground-truth positions gets +d and -d along one direction: the errors
    # do not correlate with the positions, the best alignment is the identity and every error
    # is d.
    gt = helix()
    d = 0.01
    direction = np.array([1.0, 2.0, 2.0]) / 3.0
    est = gt.copy()
    est[:, 1:4] += d * direction * np.where(np.arange(len(gt)) % 2 == 0, 1.0, -1.0)[:, None]
    result = sdoslam.evaluate(gt, est, label="noisy")
    assert result["label"] == "noisy"
    assert result["ate"]["rmse"] == pytest.approx(d, abs=1e-12)
    assert result["ate"]["std"] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(result["alignment"]["rotation"], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(result["matched"]["errors"], d, atol=1e-12)
    assert result["matched"]["estimate_aligned"].shape == (120, 3)


def test_evaluate_gives_the_numbers_of_sdoslam_eval(executable, tmp_path):
    gt = helix()
    est = gt.copy()
    est[:, 1:4] += np.random.default_rng(1).normal(0.0, 0.02, (len(gt), 3))
    fmt = ["%.6f"] + ["%.9f"] * 7
    np.savetxt(tmp_path / "gt.txt", gt, fmt=fmt)
    np.savetxt(tmp_path / "est.txt", est, fmt=fmt)
    subprocess.run([str(executable), "eval", "--gt", str(tmp_path / "gt.txt"), "--est",
                    str(tmp_path / "est.txt"), "--json", str(tmp_path / "eval.json"),
                    "--no-plots", "--delta", "10", "--delta-unit", "frames"],
                   check=True, capture_output=True)
    expected = json.loads((tmp_path / "eval.json").read_text())["estimates"][0]
    result = sdoslam.evaluate(tmp_path / "gt.txt", str(tmp_path / "est.txt"), delta=10,
                              delta_unit="frames")
    assert result["label"] == "est"
    assert result["ate"] == expected["ate"]
    assert result["rte"] == expected["rte"]
    assert result["settings"]["rte_delta_unit"] == "frames"


def test_evaluate_bad_input():
    gt = helix()
    with pytest.raises(ValueError, match="est: expected N×8"):
        sdoslam.evaluate(gt, gt[:, :7])
    unordered = gt[::-1].copy()
    with pytest.raises(ValueError, match=r"est: row 1: timestamp [0-9.]+ does not increase over the row before"):
        sdoslam.evaluate(gt, unordered)
    with pytest.raises(sdoslam.Error, match="no_such_file"):
        sdoslam.evaluate("no_such_file.txt", gt)
    with pytest.raises(sdoslam.Error, match="alignment"):
        sdoslam.evaluate(gt, gt, align="affine")


def test_synth_renders_a_sequence(static_room):
    folder, summary = static_room
    assert summary["frames"] == 30 and summary["out"] == str(folder)
    assert (folder / "rgb.txt").is_file() and (folder / "groundtruth.txt").is_file()
    with pytest.raises(sdoslam.Error, match="no_such_scenario"):
        sdoslam.synth(out=folder.parent / "other", scenario="no_such_scenario", frames=2)
    with pytest.raises(sdoslam.Error):  # an earlier sequence is replaced only when asked
        sdoslam.synth(out=folder, scenario="static_room", frames=2)


def test_run_returns_the_summary(static_room, tmp_path):
    folder, _ = static_room
    out = tmp_path / "run"
    summary = sdoslam.run(dataset=folder, config=folder / "camera.yaml", out=out,
                          mode="conventional", sequential=True)
    assert summary["frames"] == summary["requested"] == 30
    assert summary["tracked"] == 30 and not summary["interrupted"]
    assert summary["mode"] == "conventional" and summary["sequential"]
    assert summary["keyframes"] >= 1 and summary["map_points"] > 0
    assert summary["evaluation"]["ate"]["rmse"] < 0.05
    written = np.loadtxt(out / "CameraTrajectory.txt")
    np.testing.assert_allclose(summary["trajectory"], written, rtol=0, atol=1e-6)
    assert "frames" in summary["text"]


def test_run_errors(static_room, tmp_path):
    folder, _ = static_room
    with pytest.raises(ValueError, match="dataset is required"):
        sdoslam.run(config=folder / "camera.yaml", out=tmp_path / "run")
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder\n")
    with pytest.raises(sdoslam.IoError) as raised:
        sdoslam.run(dataset=folder, config=folder / "camera.yaml", out=blocker / "run")
    assert isinstance(raised.value, sdoslam.Error)
