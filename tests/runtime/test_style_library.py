"""The style library: storage, averaging over clips, blending, barycentric mixing, schedules."""
import numpy as np
import pytest

from minifilm.runtime.style_library import StyleLibrary, smoothstep


def lib3(D=16):
    rng = np.random.default_rng(0)
    return StyleLibrary({n: rng.normal(size=D) for n in ("Angry", "Old", "Zombie")})


def test_save_load_roundtrip(tmp_path):
    lib = lib3()
    lib.save(tmp_path / "styles.npz")
    back = StyleLibrary.load(tmp_path / "styles.npz")
    assert back.names == lib.names
    for n in lib.names:
        np.testing.assert_array_equal(back[n], lib[n])
    np.savez(tmp_path / "bad.npz", films=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="missing arrays"):
        StyleLibrary.load(tmp_path / "bad.npz")


def test_blend_endpoints_are_exact_and_middle_is_linear():
    lib = lib3()
    np.testing.assert_array_equal(lib.blend({"Angry": 1.0, "Old": 0.0}), lib["Angry"])
    np.testing.assert_array_equal(lib.blend({"Angry": 0.0, "Old": 1.0}), lib["Old"])
    mid = lib.blend({"Angry": 0.25, "Old": 0.75})
    np.testing.assert_allclose(mid, 0.25 * lib["Angry"].astype(float) + 0.75 * lib["Old"], rtol=1e-6)
    with pytest.raises(ValueError, match="sum to 1"):
        lib.blend({"Angry": 0.5, "Old": 0.2})
    with pytest.raises(KeyError, match="known styles"):   # also a ValueError: bad input for the command-line tools
        lib.blend({"Moonwalk": 1.0})


def test_barycentric():
    lib = lib3()
    third = lib.barycentric(["Angry", "Old", "Zombie"], [1 / 3, 1 / 3, 1 / 3])
    np.testing.assert_allclose(third, (lib["Angry"].astype(float) + lib["Old"] + lib["Zombie"]) / 3, rtol=1e-5)
    np.testing.assert_array_equal(lib.barycentric(["Angry", "Old", "Zombie"], [0, 0, 1]), lib["Zombie"])
    with pytest.raises(ValueError, match="inside the triangle"):
        lib.barycentric(["Angry", "Old", "Zombie"], [1.5, -0.5, 0])


def test_average_over_clips_uses_the_model():
    class Fake:  # FiLM = mean over time and channels of the clip, tiled: easy to compute by hand
        def film_parameters(self, clips):
            return np.repeat(clips.mean(axis=(1, 2))[:, None], 8, axis=1)

    clips = np.arange(5 * 4 * 3, dtype=float).reshape(5, 4, 3)
    lib = StyleLibrary()
    v = lib.add_from_clips("S", Fake(), clips, batch=2)
    np.testing.assert_allclose(v, np.full(8, clips.mean()))


def test_schedule_switches_smoothly():
    lib = lib3()
    F = 300
    films = lib.schedule([(0.0, "Angry"), (2.0, "Old")], n_frames=F, fps=60, transition_seconds=1.0)
    np.testing.assert_array_equal(films[0], lib["Angry"])
    np.testing.assert_array_equal(films[119], lib["Angry"])   # before the switch
    np.testing.assert_array_equal(films[180], lib["Old"])     # transition over
    # distance to the target decreases monotonically during the transition, without jumps
    d = np.linalg.norm(films[120:181] - lib["Old"], axis=1)
    assert np.all(np.diff(d) <= 1e-6)
    assert np.max(np.abs(np.diff(films, axis=0))) < 0.05 * np.max(np.abs(lib["Angry"] - lib["Old"]))


def test_smoothstep_ends():
    np.testing.assert_array_equal(smoothstep([-1, 0, 1, 2]), [0, 0, 1, 1])
    assert smoothstep(0.5) == 0.5
