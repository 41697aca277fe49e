"""The comparison's convergence curves, claim measures and verdicts, on inputs with known answers."""
import types
from pathlib import Path

import numpy as np
import pytest

from minifilm.evaluation import convergence
from minifilm.evaluation.compare_measures import hand_amplitude, pose_steps, taken_for


# ---------------------------------------------------------------------------- convergence rule
def test_the_rule_reads_the_last_fifth_of_the_steps():
    steps = list(range(0, 101, 10))
    # 100 -> 90 over the last 20 steps: 10 % improvement, still falling
    falling = [200, 180, 160, 140, 130, 120, 110, 105, 100, 95, 90]
    r = convergence.flat_at_end(steps, falling)
    assert r["flat"] is False and r["from_step"] == 80 and r["improvement"] == pytest.approx(0.1)
    # 100 -> 98: 2 %, flat
    flat = [200, 150, 120, 110, 105, 102, 101, 100.5, 100, 99, 98]
    assert convergence.flat_at_end(steps, flat)["flat"] is True
    # rising at the end (over-fitting) counts as flat
    assert convergence.flat_at_end(steps, falling[:8] + [100, 104, 108])["flat"] is True
    # the reference is the last point at or before 80 %: with points at 0, 70, 100 it is 70
    assert convergence.flat_at_end([0, 70, 100], [3.0, 2.0, 1.0])["from_step"] == 70
    # a single point cannot be judged
    assert convergence.flat_at_end([5], [1.0])["flat"] is None


def _tiny_trainer(seed, epochs=2):
    from minifilm.baselines.variants import build_variant
    from minifilm.dataset.arrays import TrainData
    from minifilm.dataset.stats import NormStats
    from minifilm.model.config import ModelConfig
    from minifilm.train.trainer import TrainConfig, Trainer
    rng = np.random.default_rng(0)
    cfg = ModelConfig(x_dim=12, z_dim=10, phase_dim=8, clip_frames=6, clip_channels=5, n_experts=2, hidden=8,
                      gating_hidden=4, conv_filters=2, conv_kernel=3, film_dense=4, dropout=0.1)
    n = 96
    style = np.repeat([0, 1], n // 2)
    x = rng.normal(size=(n, 12))
    data = TrainData(x=x, p=rng.normal(size=(n, 8)), z=np.tanh(x[:, :10]) + 0.1 * style[:, None],
                     style=style, clips=rng.normal(size=(8, 6, 5)), clip_style=np.repeat([0, 1], 4))
    model = build_variant("LPN FiLM", cfg, np.random.default_rng(seed), n_styles=2, dtype=np.float64)
    tr = Trainer(model, NormStats.identity(12, 10), TrainConfig(epochs=epochs, batch_size=8, lr=1e-2, seed=seed,
                                                                progress=False))
    return tr, data


def test_training_with_a_curve_gives_the_same_model_as_fit():
    a, data = _tiny_trainer(3)
    a.fit(data)
    b, _ = _tiny_trainer(3)
    val = convergence.validation_subset(data, frames_per_style=10, clips_per_style=2)
    curve = convergence.train_with_curve(b, data, val, epochs=2, eval_every=3)
    assert b.step == a.step and b.epoch == a.epoch == 2
    for pa, pb in zip(a.model.parameter_sets(), b.model.parameter_sets()):
        np.testing.assert_array_equal(pa.data, pb.data)
    # recorded before the first step, every 3 steps and after the last
    assert curve["steps"][0] == 0 and curve["steps"][-1] == b.step
    assert all(s % 3 == 0 for s in curve["steps"][1:-1]) and len(curve["steps"]) >= 4
    assert curve["loss"][-1] < curve["loss"][0]


class _ScriptedTrainer:
    """A trainer whose validation loss follows a script: one step per epoch."""

    def __init__(self, losses):
        self.losses, self.step, self.epoch = list(losses), 0, 0
        self.config = types.SimpleNamespace(progress=False, epochs=1)

    def evaluate(self, val):
        return {"loss": self.losses[min(self.step, len(self.losses) - 1)]}

    def minibatches(self, data):
        return [types.SimpleNamespace(style=0, index=0, count=1)]

    def train_step(self, b):
        self.step += 1
        return 0.0, 0.0

    def end_epoch(self, summary):
        self.epoch += 1

    def _summarise(self, sums):
        return {}


def test_until_flat_trains_on_while_the_loss_falls_and_stops_when_flat():
    # falling 10 % per step for 6 steps, then flat: the budget of 2 is extended until the rule holds
    losses = [1.0, 0.9, 0.81, 0.73, 0.66, 0.59, 0.53] + [0.53] * 20
    t = _ScriptedTrainer(losses)
    c = convergence.train_with_curve(t, None, None, epochs=2, eval_every=1, until_flat=True, max_epochs=50)
    assert c["flat"] is True and 6 < t.epoch < 50
    # without --until-flat the budget is the budget
    t = _ScriptedTrainer(losses)
    c = convergence.train_with_curve(t, None, None, epochs=2, eval_every=1)
    assert t.epoch == 2 and c["flat"] is False
    # a loss that never flattens stops at the maximum
    t = _ScriptedTrainer([0.9 ** k for k in range(100)])
    c = convergence.train_with_curve(t, None, None, epochs=2, eval_every=1, until_flat=True, max_epochs=9)
    assert t.epoch == 9 and c["flat"] is False


# ---------------------------------------------------------------------------- measures
def test_hand_amplitude_of_a_swinging_and_a_still_hand():
    F, a = 300, 0.2
    block = np.zeros((F, 12 * 2))
    t = np.arange(F) / 30.0
    block[:, 0] = a * np.sin(2 * np.pi * 2.0 * t)        # joint 0's x swings ±a at 2 Hz (whole cycles per window)
    cols = np.array([[0, 1, 2]])
    assert hand_amplitude(block, cols, 30) == pytest.approx(a / np.sqrt(2), rel=1e-3)
    assert hand_amplitude(block, np.array([[12, 13, 14]]), 30) == 0.0
    assert np.isnan(hand_amplitude(block[:10], cols, 30))


def test_taken_for_names_the_style_that_wins_the_windows():
    P = np.zeros((2, 4, 3))
    P[0, :, 0] = 1.0                     # character 0 asked for style 0: all windows say 0
    P[1, :3, 2], P[1, 3:, 1] = 1.0, 1.0  # character 1 asked for style 1: 3 of 4 windows say 2
    out = taken_for(P, [0, 1], ["A", "B", "C"])
    assert out["A"] == {"right": 1.0, "other": None, "other_share": 0.0, "mistaken": False}
    assert out["B"]["other"] == "C" and out["B"]["other_share"] == 0.75 and out["B"]["mistaken"]


def test_pose_steps_of_an_even_blend_and_of_a_jump():
    w = np.linspace(0, 1, 11)
    even = np.stack([np.full((5, 3), x) for x in w])                   # the statistics move linearly
    r = pose_steps(even)
    assert r["max_over_mean"] == pytest.approx(1.0) and r["first_half_share"] == pytest.approx(0.5)
    jump = np.stack([np.full((5, 3), float(x >= 0.95)) for x in w])     # first style until the very end
    r = pose_steps(jump)
    assert r["max_over_mean"] == pytest.approx(10.0) and r["first_half_share"] == 0.0


def test_thinning_a_rollout_keeps_every_other_frame():
    from minifilm.evaluation.compare_released import thin
    from minifilm.runtime.rollout import Rollout
    B, F, J = 2, 10, 3
    r = Rollout(positions=np.arange(B * F * J * 3, dtype=float).reshape(B, F, J, 3),
                rotations=np.zeros((B, F, J, 3, 3)), contacts=np.zeros((B, F, 2)), phases=np.zeros((B, F, 8)),
                root_positions=np.zeros((B, F, 2)), root_facing=np.zeros((B, F, 2)), targets=np.zeros((B, F, 2)),
                fps=60.0)
    t = thin(r, 2)
    assert t.fps == 30.0 and t.positions.shape == (B, 5, J, 3)
    np.testing.assert_array_equal(t.positions[:, 1], r.positions[:, 2])


# ---------------------------------------------------------------------------- verdicts
def _errors(mse, style="PendulumHands"):
    return {"mse": mse, "bll": mse / 10, "per_style": {style: {"mse": mse}}}


def _result(mse, hands=None, diverged=False):
    roll = {"diverged": diverged, "hands": hands or {}, "taken_for": {}}
    return {"errors": _errors(mse), "seed_errors": [_errors(mse)], "rollout": roll}


def test_figure10_verdict_follows_the_rule():
    from minifilm.evaluation.compare_claims import figure10_claim
    ctx = types.SimpleNamespace(seen=["PendulumHands"])
    good = {"LPN FiLM": _result(0.1), "PFNN FiLM": _result(0.2), "LPN one-hot": _result(0.3)}
    assert "**holds**" in "\n".join(figure10_claim(ctx, good))
    bad = {"LPN FiLM": _result(0.4), "PFNN FiLM": _result(0.2), "LPN one-hot": _result(0.3)}
    assert "**does not hold**" in "\n".join(figure10_claim(ctx, bad))


def test_stuck_arms_verdict_compares_the_lpn_with_the_others():
    from minifilm.evaluation.compare_claims import no_phase_claim
    ctx = types.SimpleNamespace(seen=["PendulumHands", "Neutral"], data_hands={"PendulumHands": 0.2})
    res = {"LPN FiLM": _result(0.1, {"PendulumHands": 0.18}),      # ratio 0.9
           "PFNN FiLM": _result(0.1, {"PendulumHands": 0.04}),     # ratio 0.2: stuck
           "MANN FiLM": _result(0.1, {"PendulumHands": 0.3})}      # ratio 1.5
    text = "\n".join(no_phase_claim(ctx, res))
    assert "0.20 (stuck)" in text and "**holds**" in text and "2 of 2" in text
    res["MANN FiLM"] = _result(0.1, {"PendulumHands": 0.19})      # ratio 0.95: closer than the LPN
    assert "**partly**" in "\n".join(no_phase_claim(ctx, res))
    none = types.SimpleNamespace(seen=["Neutral"], data_hands={})
    assert "**not judged**" in "\n".join(no_phase_claim(none, res))


def test_interpolation_pairs_parse_and_refuse():
    from minifilm.cli.compare import parse_args
    from minifilm.errors import InputError
    from minifilm.evaluation.compare import check_pairs, interpolation_pairs
    a = parse_args(["--interpolate", " A, B ; C,D"])
    assert interpolation_pairs(a.interpolate) == [("A", "B"), ("C", "D")]
    assert parse_args(["--interpolate", "A,B"]).interpolate == "A,B"
    with pytest.raises(InputError, match="several pairs"):
        parse_args(["--interpolate", "A,B;C"])
    styles = ["A", "B", "BentForward", "C", "LeanBack", "X"]
    assert check_pairs(styles, "X", None) == [("BentForward", "LeanBack")]
    assert check_pairs(["A", "B", "C"], "C", None) == [("A", "B")]
    with pytest.raises(InputError, match="not seen in training"):
        check_pairs(styles, "X", [("A", "B"), ("C", "X")])


def test_the_released_network_is_found_through_the_data_sets_description(tmp_path):
    import json
    from minifilm.dataset.manifest import MADE_BY
    from minifilm.evaluation.compare_released import released_folder, released_rollout
    data = tmp_path / "data"
    data.mkdir()
    (data / "dataset.json").write_text(json.dumps({"made_by": MADE_BY, "params": str(tmp_path / "net")}))
    args = types.SimpleNamespace(released=None, data=str(data), rollout_seconds=1.0)
    assert released_folder(args) == (tmp_path / "net", "the data set's dataset.json")
    # named by the data set but not on this machine: a note, not an error
    assert "not on this machine" in released_rollout(None, args)["skipped"]
    (data / "dataset.json").write_text(json.dumps({"made_by": "someone else", "params": "x"}))
    assert released_folder(args) == (None, None)
    assert released_folder(types.SimpleNamespace(released=None, data="synthetic")) == (None, None)


def test_a_report_names_the_network_by_its_folders_name_alone(tmp_path, monkeypatch):
    from minifilm.evaluation.compare_report_tools import report_name
    net = tmp_path / "deep" / "inside" / "released-lpn"
    net.mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "deep")
    assert report_name(net) == "released-lpn"
    assert report_name(Path("inside/released-lpn")) == "released-lpn"
    assert report_name(Path("inside/released-lpn/")) == "released-lpn"
    assert report_name("synthetic") == "synthetic"          # --data's default, not a folder
    assert report_name(str(tmp_path / "deep")) == "deep"    # --data as a string


def test_an_older_data_sets_relative_network_path_is_read_beside_the_data(tmp_path, monkeypatch):
    """Data sets made before the path was written absolutely hold it relative to where `dataset` ran."""
    import json
    from minifilm.dataset.manifest import MADE_BY
    from minifilm.evaluation.compare_released import released_folder
    data = tmp_path / "work" / "data"
    (tmp_path / "work" / "net").mkdir(parents=True)
    data.mkdir()
    (data / "dataset.json").write_text(json.dumps({"made_by": MADE_BY, "params": "../net"}))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)                    # not where the data set was made
    folder, _ = released_folder(types.SimpleNamespace(released=None, data=str(data)))
    assert folder.resolve() == (tmp_path / "work" / "net").resolve()


def test_the_reports_command_line_names_every_option_that_changes_the_numbers():
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare_report import command_options
    a = parse_args(["--lr", "5e-4", "--batch-size", "16", "--seed", "3", "--variants", "PFNN FiLM,LPN FiLM",
                    "--holdout", "Zombie", "--until-flat"])
    line = command_options(a)
    for part in ("--lr 0.0005", "--batch-size 16", "--seed 3", "--variants 'PFNN FiLM,LPN FiLM'",
                 "--holdout Zombie", "--until-flat"):
        assert part in line, (part, line)
    import shlex
    again = parse_args(shlex.split(line))                                 # as typed, it parses back
    assert (again.lr, again.batch_size, again.seed, again.variants) == (a.lr, a.batch_size, a.seed, a.variants)
    defaults = command_options(parse_args([]))
    assert "--lr" not in defaults and "--batch-size" not in defaults and "--seed" not in defaults
