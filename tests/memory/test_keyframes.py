import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navbench.memory import KeyframeSelector, PoseError, rotation_angle_deg, select_keyframes


def yaw_quat(deg: float) -> np.ndarray:
    return Rotation.from_euler("y", deg, degrees=True).as_quat()  # [x, y, z, w]


def test_straight_line_keeps_every_fourth_step_of_0_1m():
    # Steps of 0.1 m: keyframes when >= 0.25 m from the last keyframe -> frames 0, 3, 6, 9 (0.3 m apart).
    poses = [((0.0, 0.0, -0.1 * i), yaw_quat(0)) for i in range(10)]
    assert select_keyframes(poses) == [0, 3, 6, 9]


def test_rotation_in_place_measured_from_last_keyframe_not_last_frame():
    # 6 deg per frame: every 3rd frame reaches >= 15 deg (18) since the last keyframe.
    poses = [((1.0, 0.0, 2.0), yaw_quat(6 * i)) for i in range(10)]
    assert select_keyframes(poses) == [0, 3, 6, 9]
    # Slow drift: 0.06 m per frame never triggers frame-to-frame but does against the last keyframe.
    drift = [((0.06 * i, 0.0, 0.0), yaw_quat(0)) for i in range(11)]
    assert select_keyframes(drift) == [0, 5, 10]


def test_rotation_angle_uses_relative_quaternion_any_axis_and_sign():
    q = Rotation.from_euler("x", 20, degrees=True).as_quat()
    assert rotation_angle_deg(yaw_quat(0), q) == pytest.approx(20.0)
    assert rotation_angle_deg(yaw_quat(170), yaw_quat(-170)) == pytest.approx(20.0)  # wraps the short way
    assert rotation_angle_deg(yaw_quat(30), -yaw_quat(30)) == pytest.approx(0.0, abs=1e-6)  # q and -q
    # 14 deg about another axis stays below threshold, 16 deg crosses it.
    poses = [((0, 0, 0), yaw_quat(0)), ((0, 0, 0), Rotation.from_euler("x", 14, degrees=True).as_quat()),
             ((0, 0, 0), Rotation.from_euler("x", 16, degrees=True).as_quat())]
    assert select_keyframes(poses) == [0, 2]


def test_thresholds_are_configurable_and_streaming_matches_batch():
    rng = np.random.default_rng(0)
    poses = [(rng.normal(size=3) * 0.2, Rotation.random(random_state=i).as_quat()) for i in range(30)]
    sel = KeyframeSelector(translation=0.5, rotation_deg=60.0)
    batch = sel.select(poses)
    sel.reset()
    stream = [i for i, (p, q) in enumerate(poses) if sel.accept(p, q)]
    assert batch == stream and batch[0] == 0
    assert len(batch) < len(select_keyframes(poses))  # looser thresholds keep fewer


def test_bad_poses_rejected():
    with pytest.raises(PoseError, match="rotation"):
        select_keyframes([((0, 0, 0), (0, 0, 0, 0))])
    with pytest.raises(PoseError, match="position"):
        select_keyframes([((0, np.nan, 0), (0, 0, 0, 1))])
    with pytest.raises(ValueError):
        KeyframeSelector(translation=0.0)
