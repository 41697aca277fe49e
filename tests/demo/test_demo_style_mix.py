"""Smooth style changes (minifilm/demo/style_mix.py): a smoothstep in FiLM space over the given
time, starting from wherever the mix is, ending exactly on the target's vector."""
import numpy as np
import pytest

from minifilm.demo.style_mix import StyleMix
from minifilm.runtime.style_library import StyleLibrary, smoothstep


@pytest.fixture
def library():
    rng = np.random.default_rng(0)
    return StyleLibrary({name: rng.standard_normal(16) for name in ("A", "B", "C", "D")})


def test_a_change_follows_a_smoothstep_and_ends_on_the_target_exactly(library):
    mix = StyleMix(library, {"A": 1.0})
    assert np.array_equal(mix.film, library["A"])
    mix.change({"B": 1.0}, seconds=1.0)
    films = [mix.advance(1 / 60) for _ in range(60)]
    for k in (14, 29, 44):
        s = smoothstep((k + 1) / 60)
        np.testing.assert_allclose(films[k], (1 - s) * library["A"] + s * library["B"], rtol=1e-5, atol=1e-6)
    assert np.array_equal(films[-1], library["B"]) and not mix.changing
    assert mix.weights == {"B": 1.0}


def test_a_blend_at_a_corner_is_that_style_and_inside_is_the_barycentric_mix(library):
    mix = StyleMix(library, {"A": 1.0})
    mix.change({"B": 1.0, "C": 0.0, "D": 0.0}, seconds=0)      # the triangle at its B corner
    assert np.array_equal(mix.film, library["B"])
    mix.change({"B": 0.2, "C": 0.3, "D": 0.5}, seconds=0)
    np.testing.assert_allclose(mix.film, library.barycentric(["B", "C", "D"], [0.2, 0.3, 0.5]))


def test_a_change_during_a_change_starts_where_the_first_had_got_to(library):
    mix = StyleMix(library, {"A": 1.0})
    mix.change({"B": 1.0}, seconds=1.0)
    for _ in range(30):
        before = mix.advance(1 / 60)
    weights = mix.weights
    assert weights["A"] == pytest.approx(0.5) and weights["B"] == pytest.approx(0.5)
    mix.change({"C": 1.0}, seconds=1.0)
    after = mix.advance(1 / 60)
    # one frame on, the film has barely moved: no jump back to A or on to C
    assert np.abs(after - before).max() < 0.01 * np.abs(library["C"] - before).max() + 1e-6
    w = mix.weights
    assert set(w) == {"A", "B", "C"} and sum(w.values()) == pytest.approx(1.0)
    assert mix.dominant()[0] in ("A", "B")
