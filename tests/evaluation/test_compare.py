"""The comparison: the run-time adapter for the variants, style subsets, and a tiny end-to-end run."""
import numpy as np
import pytest

from minifilm.baselines.runtime import VariantRuntime
from minifilm.model.config import ModelConfig
from minifilm.baselines.variants import build_variant
from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.dataset.stats import NormStats
from minifilm.evaluation.metrics import silhouette_samples, silhouette_score

LAYOUT = FeatureLayout.for_skeleton(STYLE100)


def _stats(rng):
    L = LAYOUT
    return NormStats(rng.normal(size=L.x_dim), rng.uniform(0.5, 2, L.x_dim), rng.normal(size=L.z_dim),
                     rng.uniform(0.5, 2, L.z_dim), rng.normal(size=8), rng.uniform(0.5, 2, 8))


def _model(name, rng, n_styles=3):
    L = LAYOUT
    cfg = ModelConfig(x_dim=L.x_dim, z_dim=L.z_dim, phase_dim=8, clip_frames=8, clip_channels=L.clip_dim,
                      n_experts=2, hidden=8, gating_hidden=4, conv_filters=2, conv_kernel=3, film_dense=4,
                      dropout=0.0)
    return build_variant(name, cfg, rng, n_styles=n_styles, dtype=np.float64)


def test_lpn_onehot_runtime_equals_the_model():
    rng = np.random.default_rng(0)
    m, st = _model("LPN one-hot", rng), _stats(rng)
    x_raw, p_raw = rng.normal(size=(4, LAYOUT.x_dim)), rng.normal(size=(4, 8))
    ids = np.array([0, 2, 1, 2])
    rt = VariantRuntime(m, st, LAYOUT, {"backbone": "lpn"})
    z = rt.predict(x_raw, p_raw, ids)
    zn = m.forward((x_raw - st.x_mean) / st.x_std, (p_raw - st.p_mean) / st.p_std, None, style=ids)
    np.testing.assert_allclose(z, zn * st.z_std + st.z_mean, rtol=1e-12, atol=1e-12)
    # a one-hot weight row is the same as the style id (the one-hot term is linear in the vector)
    np.testing.assert_allclose(rt.predict(x_raw, p_raw, np.eye(3)[ids]), z, rtol=1e-10, atol=1e-10)
    # half-way weights give the mean of the two styles' first-layer shifts, not either style
    half = rt.predict(x_raw[:1], p_raw[:1], np.array([[0.5, 0.5, 0.0]]))
    assert not np.allclose(half, rt.predict(x_raw[:1], p_raw[:1], np.array([0])))


def test_pfnn_runtime_advances_the_global_phase():
    rng = np.random.default_rng(1)
    m, st = _model("PFNN one-hot", rng), _stats(rng)
    info = {"backbone": "pfnn", "phase_slot": 3, "phase_update_mean": 0.01, "phase_update_std": 0.02,
            "phase_update_column": 324, "contact_columns": (325, 327)}
    rt = VariantRuntime(m, st, LAYOUT, info)
    x_raw = rng.normal(size=(2, LAYOUT.x_dim))
    p_raw = rng.normal(size=(2, 8))
    z = rt.predict(x_raw, p_raw, np.array([1, 0]))
    phase = np.mod(np.arctan2(p_raw[:, 6], p_raw[:, 7]) / (2 * np.pi), 1.0)     # right-foot pair
    zn = m.forward((x_raw - st.x_mean) / st.x_std, phase[:, None], None, style=np.array([1, 0]))
    new = phase + zn[:, 324] * 0.02 + 0.01
    L = LAYOUT
    got = z[:, L.z_phases][:, 6:8]
    amp = np.linalg.norm(p_raw[:, 6:8], axis=1)
    np.testing.assert_allclose(got, amp[:, None] * np.stack([np.sin(2 * np.pi * new), np.cos(2 * np.pi * new)], 1),
                               atol=1e-12)
    # the controller averages (phase + update) with the phase: both must give the new phase
    np.testing.assert_allclose(p_raw + z[:, L.z_phase_updates], z[:, L.z_phases], atol=1e-12)
    zc = np.arange(L.z_contacts.start, L.z_contacts.stop)
    np.testing.assert_allclose(z[:, zc], zn[:, 325:327] * st.z_std[zc] + st.z_mean[zc], atol=1e-12)


def test_tiny_compare_run(tmp_path):
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare import run
    args = parse_args(["--tiny", "--variants", "LPN FiLM,LPN one-hot", "--budget-steps", "1",
                       "--finetune-steps", "1", "--seconds", "8", "--styles", "Neutral,LeftHop,Crouched",
                       "--gaits", "FW", "--holdout", "Crouched", "--rollout-seconds", "2",
                       "--work", str(tmp_path / "work"), "--out", str(tmp_path / "reports")])
    out = run(args)
    ctx = out["ctx"]
    assert ctx.seen == ["LeftHop", "Neutral"] and ctx.holdouts == ["Crouched"]
    # the held-out style is in no training array
    assert set(ctx.data["train"].style_names) == set(ctx.seen)
    for v in ("LPN FiLM", "LPN one-hot"):
        r = out["results"][v]
        assert np.isfinite(r["errors"]["mse"]) and r["errors"]["mse"] > 0
        assert set(r["errors"]["per_style"]) == set(ctx.seen)
    ft = out["finetune"]
    assert ft is not None and ft["steps"] >= 1
    # fine-tuning moved Ψ: the held-out style's error changed, and the separations reported are
    # those of the FiLM codes' embedding it returns
    assert ft["after_new"]["mse"] != ft["before_new"]["mse"]
    labels = np.asarray(ft["labels"])
    for tag in ("before", "after"):
        sep = ft["separation"][tag]
        assert sep["silhouette_2d"] == pytest.approx(silhouette_score(sep["embedding"], labels), abs=1e-12)
        focus = silhouette_samples(sep["embedding"], labels)[labels == len(ctx.seen)].mean()
        assert sep["focus_silhouette_2d"] == pytest.approx(focus, abs=1e-12)
    text = out["report"].read_text()
    assert "LPN FiLM" in text and "LPN one-hot" in text and "Figure 10" in text


def test_several_styles_held_out_are_taught_to_every_film_variant_and_only_psi_moves(tmp_path):
    """Two held-out styles, the three FiLM variants: each is fine-tuned (Ψ alone: the backbone's
    weights stay bit for bit), each held-out style gets its own figures, and the rollouts carry the
    pooled FID-like distance."""
    from minifilm.baselines.variant_data import variant_data
    from minifilm.baselines.variants import model_from_checkpoint
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare import run
    from minifilm.evaluation.compare_finetune import FILM_VARIANTS, checkpoint_name
    from minifilm.train.finetune import finetune
    from minifilm.train.trainer import TrainConfig, Trainer
    args = parse_args(["--tiny", "--variants", ",".join(FILM_VARIANTS), "--budget-steps", "1",
                       "--finetune-steps", "2", "--seconds", "8", "--styles", "Neutral,LeftHop,Crouched,Limp",
                       "--gaits", "FW", "--holdout", "Limp, Crouched", "--rollout-seconds", "2", "--extra-seeds", "",
                       "--workers", "1", "--work", str(tmp_path / "work"), "--out", str(tmp_path / "reports")])
    out = run(args)
    ctx = out["ctx"]
    assert ctx.holdouts == ["Limp", "Crouched"] and ctx.seen == ["LeftHop", "Neutral"]
    assert set(ctx.data["train"].style_names) == set(ctx.seen)
    assert list(out["finetuned"]) == list(FILM_VARIANTS) and out["finetune"] is out["finetuned"]["LPN FiLM"]
    for v, ft in out["finetuned"].items():
        assert set(ft["after_new"]["per_style"]) == {"Limp", "Crouched"}
        assert ft["after_new"]["mse"] != ft["before_new"]["mse"], v
        # the held-out styles are the last labels, in the order given
        assert set(ft["separation"]["after"]["focus_each"]) == {2, 3}
        labels = np.asarray(ft["labels"])
        assert set(labels[np.isin(labels, [2, 3])]) == {2, 3}
        q = out["results"][v]["rollout"]
        assert q["diverged"] or (q["fid"] >= 0 and np.isfinite(q["fid"]))
    text = out["report"].read_text()
    assert "Figure 11: a new style" in text and "FID-like" in text
    assert all(f"| {v} | after |" in text for v in FILM_VARIANTS)
    assert "| Limp | MSE " in text and "| Crouched | MSE " in text
    assert "n/a (run for LPN FiLM)" not in text
    # Ψ alone moves: fine-tune each variant's saved base again and compare its networks
    for v in FILM_VARIANTS:
        path = tmp_path / "work" / checkpoint_name(v)
        base = Trainer.resume(path, build_model=model_from_checkpoint).model
        data = variant_data(v, ctx.new_train, ctx.layout, ctx.norm, ctx.end_effectors,
                            reference=out["results"][v]["info"])[0]
        tuned = finetune(path, data, config=TrainConfig(epochs=1, batch_size=8, seed=3, progress=False),
                         build_model=model_from_checkpoint).model
        for net in ("gating", "motion"):
            if getattr(base, net) is not None:
                for name, w in getattr(base, net).params.state_dict().items():
                    assert np.array_equal(w, getattr(tuned, net).params.state_dict()[name]), (v, net, name)
        assert any(not np.array_equal(w, tuned.film.params.state_dict()[name])
                   for name, w in base.film.params.state_dict().items()), v


def test_held_out_names_are_read_once_each_in_order_and_checked():
    from minifilm.errors import InputError
    from minifilm.evaluation.compare import check_pairs, holdout_names
    assert holdout_names(" B, A ,,B") == ["B", "A"] and holdout_names(None) == []
    with pytest.raises(InputError, match="'Z' not a style of the data"):
        check_pairs(["A", "B", "C", "D"], ["A", "Z"], None)
    with pytest.raises(InputError, match="two must be seen"):
        check_pairs(["A", "B", "C"], ["A", "B"], None)
    assert check_pairs(["A", "B", "C", "D"], ["A", "B"], None) == [("C", "D")]


def test_claims_use_seed_means():
    import types
    from minifilm.evaluation.compare_report import claims, seed_summary

    def e(m):
        return {"mse": m, "bll": 0.0, "per_style": {"Swimming": {"mse": m}}}
    res = {"LPN FiLM": {"errors": e(1.0), "seed_errors": [e(1.0), e(1.2)]},          # mean 1.1
           "PFNN one-hot": {"errors": e(0.9), "seed_errors": [e(0.9), e(1.5)]},      # mean 1.2: seed 0 alone would win
           "PFNN FiLM": {"errors": e(0.9), "seed_errors": [e(0.9), e(1.0)]}}         # mean 0.95
    s = seed_summary(res["PFNN one-hot"])
    assert s["mse"] == pytest.approx(1.2) and s["mse_sd"] == pytest.approx(np.std([0.9, 1.5], ddof=1))
    text = claims(types.SimpleNamespace(seen=["Swimming"], holdouts=[]), res, None)
    assert "lowest test error: **holds**" in text[0]
    assert "LPN lowest on 0 of 1" in text[1]


def test_a_number_of_styles_spreads_over_the_names_and_keeps_the_named_ones():
    from minifilm.evaluation.compare_tools import select_styles
    names = [f"S{i:03d}" for i in range(100)]
    picked = select_styles(names, ["5"])
    assert picked == ["S000", "S025", "S050", "S074", "S099"]
    kept = select_styles(names, ["4"], keep=["S042", "S043"])
    assert len(kept) == 4 and {"S042", "S043"} <= set(kept)
    assert select_styles(names, None) == names
    assert select_styles(names, ["S002", " S001"]) == ["S001", "S002"]


@pytest.mark.parametrize("spec, words", [(["2"], "between 3 and 100"), (["101"], "between 3 and 100"),
                                          (["Nope"], "'Nope' not in the data")])
def test_a_style_subset_outside_the_data_is_refused(spec, words):
    from minifilm.evaluation.compare_tools import select_styles
    with pytest.raises(ValueError, match=words):
        select_styles([f"S{i:03d}" for i in range(100)], spec)


def test_a_compare_run_of_the_default_model_writes_its_report(tmp_path):
    """Without --tiny the variants are the main job's model, whose sizes are the config's own (the
    options hold only what they change): the report names the sizes the variants were built with."""
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare import run
    args = parse_args(["--variants", "LPN FiLM", "--budget-steps", "1", "--finetune-steps", "1",
                       "--seconds", "8", "--styles", "Neutral,LeftHop,Crouched", "--gaits", "FW",
                       "--holdout", "Crouched", "--rollout-seconds", "2", "--extra-seeds", "",
                       "--work", str(tmp_path / "work"), "--out", str(tmp_path / "reports")])
    run(args)
    report = next((tmp_path / "reports").glob("*.md")).read_text(encoding="utf-8")
    assert "Small models: hidden 128, 4 experts, Ψ conv 32 filters / dense 128" in report


def _released_folder(path, styles):
    """A small network in the released layout (random weights) knowing ``styles``."""
    from minifilm.dataset.stats import NormStats
    from minifilm.model.style_model import StyleModel
    from minifilm.runtime.released import write_released
    L = LAYOUT
    cfg = ModelConfig(x_dim=L.x_dim, z_dim=L.z_dim, phase_dim=8, clip_frames=8, clip_channels=L.clip_dim,
                      n_experts=2, hidden=8, gating_hidden=4, conv_filters=2, conv_kernel=3, film_dense=4)
    rng = np.random.default_rng(5)
    model = StyleModel(cfg, rng, dtype=np.float32, with_film_generator=False)
    stats = NormStats.identity(L.x_dim, L.z_dim)
    write_released(model, stats, {s: np.ones(cfg.film_dim, np.float32) for s in styles}, path)
    return path


def test_tiny_compare_run_records_curves_judges_the_claims_and_drives_the_released_network(tmp_path):
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare import run
    released = _released_folder(tmp_path / "released", ["LeftHop", "Neutral", "Elsewhere"])
    args = parse_args(["--tiny", "--variants", "LPN FiLM,LPN one-hot,PFNN FiLM", "--budget-steps", "5",
                       "--finetune-steps", "1", "--seconds", "8", "--styles", "Neutral,LeftHop,PendulumHands,Crouched",
                       "--gaits", "FW", "--holdout", "Crouched", "--rollout-seconds", "2",
                       "--interpolate", "Neutral,LeftHop;PendulumHands,Neutral", "--released", str(released),
                       "--work", str(tmp_path / "work"), "--out", str(tmp_path / "reports")])
    out = run(args)
    for v, r in out["results"].items():
        assert set(r["curves"]) == {0, 1}                  # both seeds' curves
        for c in r["curves"].values():
            assert c["steps"][0] == 0 and c["steps"][-1] == r["steps"] and len(c["steps"]) >= 3
            assert c["flat"] in (True, False)
    # both interpolation pairs for the FiLM and one-hot variants
    assert set(out["results"]["LPN one-hot"]["interps"]) == {("Neutral", "LeftHop"), ("PendulumHands", "Neutral")}
    # the released network ran in the seen styles it knows (PendulumHands is not among them)
    rel = out["released"]
    assert rel["styles"] == ["LeftHop", "Neutral"] and rel["named_by"] == "--released"
    assert set(out["table2"]) == set(out["results"])
    text = out["report"].read_text(encoding="utf-8")
    assert "## Convergence: validation curves" in text and "| released network (2 styles) |" in text
    for heading in ("### Figure 10", "### Sec. 5.1.1", "### Sec. 5.1.2", "### Figure 8", "### Table 2",
                    "### Sec. 5.3.2"):
        assert heading in text
    assert text.count("*Verdict:* **") == 6
    assert (tmp_path / "reports" / "compare_synthetic_validation.png").is_file() or "validation curves](" not in text
    assert "PendulumHands -> Neutral" in text


TINY_RUN = ["--tiny", "--variants", "LPN FiLM,PFNN one-hot", "--budget-steps", "5", "--finetune-steps", "1",
            "--seconds", "8", "--styles", "Neutral,LeftHop,Crouched", "--gaits", "FW", "--holdout", "Crouched",
            "--rollout-seconds", "2"]


def test_worker_processes_give_the_results_of_one_process(tmp_path):
    """Every run trained in a worker (minifilm/parallel.py: spawned, one BLAS thread) gives the
    figures of this process: same seeds, same code, the weights handed back as trained. To a
    tolerance, not bit for bit: the workers run one BLAS thread and this test process may run more,
    or another kernel (another CPU), which sums in another order -- float32 round-off, 6e-8 relative
    per operation, which five Adam steps carry into the weights (1e-4) and the errors (1e-6)."""
    import multiprocessing
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare import run
    outs = {}
    for w in (1, 2):
        outs[w] = run(parse_args(TINY_RUN + ["--workers", str(w), "--work", str(tmp_path / f"work{w}"),
                                             "--out", str(tmp_path / f"reports{w}")]))
    assert multiprocessing.active_children() == []              # no worker left behind
    for v in ("LPN FiLM", "PFNN one-hot"):
        one, two = outs[1]["results"][v], outs[2]["results"][v]
        assert one["steps"] == two["steps"] and one["params"] == two["params"]
        for e1, e2 in zip(one["seed_errors"], two["seed_errors"]):
            assert e1["mse"] == pytest.approx(e2["mse"], rel=1e-6) and e1["bll"] == pytest.approx(e2["bll"], rel=1e-6)
        for seed in (0, 1):
            np.testing.assert_allclose(one["curves"][seed]["loss"], two["curves"][seed]["loss"], rtol=1e-6)
            assert one["curves"][seed]["steps"] == two["curves"][seed]["steps"]
        for p1, p2 in zip(one["trainer"].model.parameter_sets(), two["trainer"].model.parameter_sets()):
            np.testing.assert_allclose(p1.data, p2.data, rtol=1e-4, atol=1e-5)
        q1, q2 = one["rollout"], two["rollout"]
        assert q1["diverged"] == q2["diverged"]
    f1, f2 = outs[1]["finetune"], outs[2]["finetune"]
    assert f1["after_new"]["mse"] == pytest.approx(f2["after_new"]["mse"], rel=1e-5)


def test_a_run_that_fails_in_a_worker_is_its_own_error_naming_the_run(tmp_path):
    import multiprocessing
    from types import SimpleNamespace
    from minifilm.cli.compare import parse_args
    from minifilm.evaluation.compare import load_data, trained_runs
    args = parse_args(TINY_RUN + ["--workers", "2", "--work", str(tmp_path / "work"), "--out", str(tmp_path / "r")])
    load_data(args)            # the data and its cache first, as run() makes them before the workers start
    with pytest.raises(ValueError, match="unknown variant 'No Such Variant'") as info:
        trained_runs(["LPN FiLM", "No Such Variant"], SimpleNamespace(args=args, holdouts=["Crouched"]), 1)
    assert info.value.__notes__ == ["(while training No Such Variant, seed 0)"]
    assert multiprocessing.active_children() == []
