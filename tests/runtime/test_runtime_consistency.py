"""The runtime sees what training saw: Controller.build_input / _apply_output against the dataset.

A synthetic clip is turned into training rows by the dataset code
(:func:`minifilm.features.compute.frame_features_from_arrays`). The Controller is then put in the
TRUE state of frame k (root history, future trajectory, joints, phases), and

* ``build_input()`` must reproduce the dataset's x row of frame k column for column (same frame
  of reference, same trajectory sample times, including the rounding of
  :func:`minifilm.features.compute.trajectory_offsets` at frame rates where a sample falls on half
  a frame, e.g. -1/6 s at 15 fps);
* feeding the dataset's TRUE z row of frame k through the output path (``_apply_output``) must
  move the state to the true frame k+1: root, facing, joints, phases (the §10.2 step 7 rule
  ``0.5 p_pred + 0.5 (p + Δp_pred)`` gives exactly the true next phase when the prediction is the
  truth), the past trajectory, and the next frame's input.

Expected values come from the dataset code and the generator, never from the runtime itself.
"""
import numpy as np
import pytest

from minifilm.synthetic import generator as synthetic
from minifilm.features.compute import frame_features_from_arrays, motion_arrays, trajectory_offsets
from minifilm.features.layout import CURRENT_SAMPLE, FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.dataset.stats import NormStats
from minifilm.runtime.controller import Controller


class _NoNetwork:
    """Only the sizes and statistics the Controller reads; build_input/_apply_output never predict."""

    def __init__(self, layout):
        self.x_dim, self.z_dim = layout.x_dim, layout.z_dim
        self.stats = NormStats.identity(layout.x_dim, layout.z_dim)


def _clip(fps, gait="TR", style="Drunk", seconds=4.0, seed=3):
    clip = synthetic.generate_style(style, gait, seconds, np.random.default_rng(seed), fps=fps)
    arrays = motion_arrays(clip.motion, STYLE100, fps)
    ang = 2 * np.pi * clip.true_phase
    amp = np.linspace(0.5, 1.5, 4)                       # distinct amplitudes per slot
    phases = np.stack([amp * np.sin(ang), amp * np.cos(ang)], axis=-1).reshape(-1, 8)
    layout = FeatureLayout.for_skeleton(STYLE100)
    feats = frame_features_from_arrays(*arrays, phases, clip.true_contacts, fps, dtype=np.float64,
                                       layout=layout)
    return arrays, phases, layout, feats


def _xz(v):
    return np.asarray(v)[..., [0, 2]]


def _true_state(ctl, arrays, phases, k, fps, layout):
    """The Controller state a perfect rollout would have at frame k (one character)."""
    positions, rotations, vel, root_pos, root_rot = arrays
    ctl.reset(np.zeros((1, 2)), np.array([[0.0, 1.0]]))
    st = ctl.state
    facing = _xz(root_rot[:, :, 2])
    n = np.arange(ctl.history, 0, -1)                    # hist[:, -n] = root n frames ago
    st.history_pos = _xz(root_pos[k - n])[None].copy()
    st.history_dir = facing[k - n][None].copy()
    fut = k + trajectory_offsets(fps, layout.trajectory_seconds)[CURRENT_SAMPLE:]
    st.future_pos = _xz(root_pos[fut])[None].copy()
    st.future_dir = facing[fut][None].copy()
    st.root, st.facing = _xz(root_pos[k])[None].copy(), facing[k][None].copy()
    st.joint_pos = positions[k][None].copy()
    st.joint_fwd = rotations[k][None, :, :, 2].copy()
    st.joint_up = rotations[k][None, :, :, 1].copy()
    st.joint_vel = vel[k][None].copy()
    st.phases = phases[k][None].copy()


@pytest.mark.parametrize("fps", [60, 30, 15])
def test_build_input_reproduces_dataset_x(fps):
    arrays, phases, layout, feats = _clip(fps)
    ctl = Controller(_NoNetwork(layout), layout, fps=fps)
    first = int(-trajectory_offsets(fps, layout.trajectory_seconds)[0])
    last = len(arrays[0]) - 1 - int(trajectory_offsets(fps, layout.trajectory_seconds)[-1])
    rows = [i for i, k in enumerate(feats.frames) if first <= k <= last]   # no reflected samples
    assert len(rows) > 10
    for i in rows[:: max(1, len(rows) // 12)]:
        k = int(feats.frames[i])
        _true_state(ctl, arrays, phases, k, fps, layout)
        x = ctl.build_input()[0]
        bad = np.flatnonzero(np.abs(x - feats.x[i]) > 1e-9)
        assert bad.size == 0, (f"{fps} fps frame {k}: build_input differs from the dataset x in columns "
                               f"{[layout.describe('x')[c] for c in bad[:4]]}")
        np.testing.assert_allclose(ctl.state.phases[0], feats.p[i], atol=1e-12)


@pytest.mark.parametrize("fps", [60, 15])
@pytest.mark.parametrize("velocity_blend", [1.0, 0.5])
def test_true_output_moves_state_to_next_frame(fps, velocity_blend):
    arrays, phases, layout, feats = _clip(fps)
    positions, rotations, vel, root_pos, root_rot = arrays
    ctl = Controller(_NoNetwork(layout), layout, fps=fps, velocity_blend=velocity_blend, future_smoothing=0.0)
    offs = trajectory_offsets(fps, layout.trajectory_seconds)
    index = {int(k): i for i, k in enumerate(feats.frames)}
    ks = [k for k in feats.frames if -offs[0] + 1 <= k <= len(positions) - 2 - offs[-1]]
    for k in ks[:: max(1, len(ks) // 10)]:
        k = int(k)
        _true_state(ctl, arrays, phases, k, fps, layout)
        ctl._apply_output(feats.z[index[k]][None])
        st = ctl.state
        np.testing.assert_allclose(st.root[0], _xz(root_pos[k + 1]), atol=1e-9)
        np.testing.assert_allclose(st.facing[0], _xz(root_rot[k + 1][:, 2]) /
                                   np.linalg.norm(_xz(root_rot[k + 1][:, 2])), atol=1e-9)
        np.testing.assert_allclose(st.joint_pos[0], positions[k + 1], atol=1e-9)
        np.testing.assert_allclose(st.joint_fwd[0], rotations[k + 1][:, :, 2], atol=1e-9)
        np.testing.assert_allclose(st.joint_up[0], rotations[k + 1][:, :, 1], atol=1e-9)
        np.testing.assert_allclose(st.joint_vel[0], vel[k + 1], atol=1e-9)
        np.testing.assert_allclose(st.phases[0], phases[k + 1], atol=1e-12)   # §10.2 step 7 rule
        np.testing.assert_allclose(st.history_pos[0, -1], _xz(root_pos[k]), atol=1e-12)
        # ... and the next input is the dataset's x of frame k+1
        if k + 1 in index:
            x = ctl.build_input()[0]
            np.testing.assert_allclose(x, feats.x[index[k + 1]], atol=1e-8,
                                       err_msg=f"{fps} fps: input after one true step, frame {k + 1}")


def test_future_smoothing_keeps_root_and_joints_exact():
    """The demo's smoothing of the future trajectory (weight 0.15) must not touch the root delta."""
    fps = 60
    arrays, phases, layout, feats = _clip(fps)
    positions, rotations, vel, root_pos, root_rot = arrays
    ctl = Controller(_NoNetwork(layout), layout, fps=fps, future_smoothing=0.15)
    k = int(feats.frames[len(feats) // 2])
    _true_state(ctl, arrays, phases, k, fps, layout)
    ctl._apply_output(feats.z[len(feats) // 2][None])
    np.testing.assert_allclose(ctl.state.root[0], _xz(root_pos[k + 1]), atol=1e-9)
    np.testing.assert_allclose(ctl.state.joint_pos[0], positions[k + 1], atol=1e-9)


def test_start_from_a_data_frame_reproduces_its_input():
    """reset(start_x=x) puts the character in x's pose and trajectory: the first input is x again
    (the history between the past samples is interpolated, the samples themselves are exact),
    wherever the character stands and whichever way it faces."""
    fps = 60
    arrays, phases, layout, feats = _clip(fps)
    ctl = Controller(_NoNetwork(layout), layout, fps=fps)
    rows = feats.x[[60, 120, 180]]
    ctl.reset(np.array([[1.0, -2.0], [0.0, 0.0], [5.0, 3.0]]), np.array([[1.0, 0.0], [0.0, 1.0], [-0.6, -0.8]]),
              phases=feats.p[[60, 120, 180]], start_x=rows)
    np.testing.assert_allclose(ctl.build_input(), rows, atol=1e-9)
    np.testing.assert_allclose(ctl.state.phases, feats.p[[60, 120, 180]])
    ctl.reset(np.zeros((2, 2)), np.array([[0.0, 1.0], [1.0, 0.0]]), start_x=rows[0])   # one row for all
    np.testing.assert_allclose(ctl.build_input(), rows[[0, 0]], atol=1e-9)
    with pytest.raises(ValueError, match="start_x"):
        ctl.reset(np.zeros((2, 2)), np.array([[0.0, 1.0], [1.0, 0.0]]), start_x=rows)
