"""The two figures of the docs (scripts/figure_model.py, scripts/figure_phase_pipeline.py).

The model figure's shapes come from the configuration: with the paper's configuration they are the
paper's numbers (Sec. 3.2 and 4.3, typed here from the paper), and they change with the config.
Both scripts write a PNG small enough for the docs (tests/test_docs.py allows 200 KB), and every
``path::name`` on the phase figure names a file and a function that exist.
"""
from __future__ import annotations

import ast
import importlib.util
import sys

import pytest

from minifilm.model.config import ModelConfig
from repo_paths import REPO_ROOT, SHARED_DATA, need_data

pytest.importorskip("matplotlib", reason="the figures need matplotlib (pip install 'minifilm[viz]')")
pytest.importorskip("PIL", reason="the figures are saved with Pillow (pip install 'minifilm[viz]')")


def load(name):
    spec = importlib.util.spec_from_file_location(name, REPO_ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def edges(chain):
    return [edge for _, edge in chain if edge is not None]


def test_the_model_figure_shows_the_paper_s_shapes():
    psi, phi, omega = load("figure_model").rows(ModelConfig.paper())
    # Sec. 3.2: a clip is 240 frames x 300 features; Sec. 4.3: 256 filters of width 25, two 2x
    # poolings, 2048 hidden units, four 512-vectors; Φ 348 -> 512 -> 512 -> 342 with 8 experts;
    # Ω 8 -> 32 -> 32 -> 8
    assert edges(psi) == ["(B, 240, 300)", "(B, 240, 256)", "(B, 120, 256)", "(B, 120, 256)", "(B, 60, 256)",
                          "(B, 15360)", "(B, 2048)", "(B, 2048)"]
    assert edges(phi) == ["(B, 348)"] + ["(B, 512)"] * 8 + ["(B, 342)"]
    assert edges(omega) == ["(B, 8)", "(B, 32)", "(B, 32)", "(B, 8)"]
    boxes = " ".join(text for text, _ in phi + psi)
    for weight in ("W0 (8, 348, 512)", "W1 (8, 512, 512)", "W2 (8, 512, 342)", "W (25, 300, 256)",
                   "W (15360, 2048)", "W (2048, 2048)"):
        assert weight in boxes


def test_the_model_figure_follows_the_configuration():
    figure = load("figure_model")
    psi, phi, _ = figure.rows(ModelConfig(hidden=64, n_experts=3, clip_frames=100))
    assert "(B, 64)" in edges(phi) and "(B, 256)" in edges(psi)        # FiLM: 4 x 64
    assert "(B, 6400)" in edges(psi)                                   # 25 pooled frames x 256 filters
    assert any("W0 (3, 348, 64)" in text for text, _ in phi)
    small = figure.small_config()
    assert small.clip_frames == 120 and small.hidden == 128            # 2 s at 60 fps; the small model


def test_the_model_figure_is_written_small(tmp_path, monkeypatch):
    out = tmp_path / "model.png"
    monkeypatch.setattr(sys, "argv", ["figure_model.py", "--out", str(out)])
    load("figure_model").main()
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and 10_000 < out.stat().st_size < 200_000


def defined(path, name):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
            names |= {f"{node.name}.{sub.name}" for sub in node.body if isinstance(sub, ast.FunctionDef)}
    return name in names


def test_the_phase_figure_names_functions_that_exist():
    figure = load("figure_phase_pipeline")
    refs = [figure.ref(fn) for _, fn in figure.PANELS]
    assert len(refs) == 6
    for ref in refs:
        path, name = ref.split("::")
        assert (REPO_ROOT / path).is_file(), ref
        assert defined(REPO_ROOT / path, name), ref


def test_the_phase_figure_is_drawn_from_a_real_walk(tmp_path, monkeypatch):
    bvh = need_data(SHARED_DATA / "bandai2" / "dataset-2_walk_normal_001.bvh", "a Bandai-Namco walk")
    out = tmp_path / "phases.png"
    monkeypatch.setattr(sys, "argv", ["figure_phase_pipeline.py", "--bvh", str(bvh), "--out", str(out)])
    load("figure_phase_pipeline").main()
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and 10_000 < out.stat().st_size < 200_000
