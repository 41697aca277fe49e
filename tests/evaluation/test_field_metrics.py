"""The field's standard metrics on motion whose answer is known by construction."""
import numpy as np
import pytest

from minifilm.evaluation.field_metrics import body_facing, fid_like, foot_sliding, trajectory_errors
from minifilm.evaluation.style_measures import StyleSpace

FPS = 60.0


def two_feet(frames, left_step, right_step, left_height=0.0, right_height=0.0, root_step=(0.0, 0.0)):
    """Joints: 0 root, 1 left toe, 2 right toe. Each moves a fixed (x, z) per frame."""
    P = np.zeros((frames, 3, 3))
    k = np.arange(frames)[:, None]
    P[:, 0, [0, 2]] = k * np.asarray(root_step)
    P[:, 0, 1] = 0.9
    P[:, 1, [0, 2]] = k * np.asarray(left_step)
    P[:, 2, [0, 2]] = k * np.asarray(right_step)
    P[:, 1, 1] = left_height
    P[:, 2, 1] = right_height
    return P


def test_a_foot_sliding_one_centimetre_per_frame_reads_sixty_cm_per_second():
    P = two_feet(120, left_step=(0.01, 0.0), right_step=(0.0, 0.01), root_step=(0.02, 0.0))
    m = foot_sliding(P, feet=[1, 2], fps=FPS)
    assert m["speed_cm_s"] == pytest.approx(60.0)
    assert m["per_frame_cm"] == pytest.approx(1.0)
    assert m["relative"] == pytest.approx(0.5)       # 1 cm of sliding per 2 cm the body travels
    assert m["contact_share"] == pytest.approx(1.0)


def test_planted_feet_do_not_slide_and_raised_feet_are_not_judged():
    # left foot planted; right foot slides fast but 20 cm up: it is swinging, not sliding
    P = two_feet(60, left_step=(0.0, 0.0), right_step=(0.05, 0.0), right_height=0.2)
    m = foot_sliding(P, feet=[1, 2], fps=FPS)
    assert m["speed_cm_s"] == pytest.approx(0.0)
    assert m["contact_share"] == pytest.approx(0.5)


def test_the_floor_is_the_lowest_foot_unless_given():
    # both feet float 30 cm up and slide: by default the lowest foot defines the floor (CAMDM)
    P = two_feet(60, left_step=(0.02, 0.0), right_step=(0.02, 0.0), left_height=0.3, right_height=0.3)
    assert foot_sliding(P, [1, 2], FPS)["speed_cm_s"] == pytest.approx(120.0)
    assert foot_sliding(P, [1, 2], FPS, floor=0.0)["contact_share"] == 0.0


@pytest.mark.parametrize("bad", [np.zeros((1, 3, 3)), np.zeros((10, 3))])
def test_foot_sliding_refuses_bad_shapes(bad):
    with pytest.raises(ValueError, match="positions"):
        foot_sliding(bad, [1], FPS)


def test_foot_sliding_refuses_joints_outside_the_skeleton():
    with pytest.raises(ValueError, match="not joints"):
        foot_sliding(np.zeros((5, 3, 3)), [3], FPS)


def shoulders_and_hips(yaw_degrees):
    """Joints 0 l-shoulder, 1 r-shoulder, 2 l-hip, 3 r-hip of a body turned by yaw about y from
    facing +z (left = +x)."""
    a = np.radians(np.asarray(yaw_degrees, np.float64))
    left = np.stack([np.cos(a), np.zeros_like(a), -np.sin(a)], axis=-1)   # +x turned by yaw
    P = np.zeros((len(a), 4, 3))
    P[:, 0], P[:, 1] = 0.2 * left + [0, 1.4, 0], -0.2 * left + [0, 1.4, 0]
    P[:, 2], P[:, 3] = 0.1 * left + [0, 0.9, 0], -0.1 * left + [0, 0.9, 0]
    return P


def test_body_facing_reads_the_turn():
    yaw = np.array([0.0, 45.0, 90.0, -135.0])
    np.testing.assert_allclose(body_facing(shoulders_and_hips(yaw), 0, 1, 2, 3), yaw, atol=1e-9)


def test_a_root_on_the_path_has_no_error():
    t = np.arange(120) / FPS
    path = np.stack([np.sin(t), t], axis=-1)
    e = trajectory_errors(path, path.copy(), np.zeros(120), np.zeros(120))
    assert e["position_mean"] == 0.0 and e["direction_mean"] == pytest.approx(0.0, abs=1e-9)
    assert e["facing_mean"] == 0.0


def test_a_root_beside_the_path_and_walking_off_at_an_angle():
    t = np.arange(121) / FPS
    path = np.stack([np.zeros_like(t), 1.0 * t], axis=-1)                     # 1 m/s along +z
    beside = path + [0.3, 0.0]
    assert trajectory_errors(beside, path)["position_mean"] == pytest.approx(0.3)
    a = np.radians(30.0)
    off = np.stack([np.sin(a) * t, np.cos(a) * t], axis=-1)                   # 30° towards +x
    e = trajectory_errors(off, path)
    assert e["direction_mean"] == pytest.approx(30.0)
    assert e["position_max"] == pytest.approx(np.hypot(np.sin(a) * 2, np.cos(a) * 2 - 2))


def test_direction_errors_either_side_cancel_only_in_the_signed_figure():
    t = np.arange(121) / FPS
    path = np.stack([np.zeros_like(t), t], axis=-1)
    zig = np.cumsum(np.where(np.arange(121)[:, None] % 2 == 0, [0.2, 1.0], [-0.2, 1.0]), axis=0) / FPS
    e = trajectory_errors(zig, path)
    assert e["direction_mean"] == pytest.approx(np.degrees(np.arctan(0.2)), rel=1e-6)
    assert e["direction_signed"] < 1.0


def test_facing_errors_wrap_around():
    e = trajectory_errors(np.zeros((3, 2)), np.zeros((3, 2)), np.array([179.0, 179.0, 179.0]),
                          np.array([-179.0, -179.0, -179.0]))
    assert e["facing_mean"] == pytest.approx(2.0)


def test_a_root_that_stands_on_a_moving_path_is_stalled_not_on_course():
    t = np.arange(61) / FPS
    path = np.stack([np.zeros_like(t), t], axis=-1)
    e = trajectory_errors(np.zeros((61, 2)), path)
    assert e["stalled"] == pytest.approx(1.0) and e["direction_mean"] == 0.0


def test_a_standing_command_has_no_direction_error():
    rng = np.random.default_rng(0)
    root = rng.normal(0, 0.001, (60, 2))
    assert trajectory_errors(root, np.zeros((60, 2)))["direction_mean"] == 0.0


def test_trajectory_errors_refuse_mismatched_inputs():
    with pytest.raises(ValueError, match="root"):
        trajectory_errors(np.zeros((10, 2)), np.zeros((9, 2)))
    with pytest.raises(ValueError, match="both"):
        trajectory_errors(np.zeros((10, 2)), np.zeros((10, 2)), facing_deg=np.zeros(10))


def test_fid_like_is_zero_for_the_same_windows_and_grows_with_a_shift():
    rng = np.random.default_rng(1)
    real = {s: rng.normal(i, 1.0, (200, 8)) for i, s in enumerate("ab")}
    space = StyleSpace.fit(real, dims=4, summarised=True)
    pooled = np.concatenate(list(real.values()))
    assert fid_like(space, pooled, pooled, summarised=True) == pytest.approx(0.0, abs=1e-9)
    near = fid_like(space, pooled + 0.1, pooled, summarised=True)
    far = fid_like(space, pooled + 1.0, pooled, summarised=True)
    assert 0 < near < far
