"""Parameters: one flat buffer with named views, state dicts, initialisers."""
import math

import numpy as np
import pytest

from minifilm.nn.params import Parameters, init_he_normal, init_uniform_fan


# ------------------------------------------------------------------------------ Parameters
def test_parameters_are_views_into_one_buffer():
    p = Parameters({"W": (3, 4), "b": 4, "E": (2, 3, 4)})
    assert p.size == 12 + 4 + 24 and p.data.shape == (40,) and p.data.dtype == np.float32
    p.params["W"][1, 2] = 5.0
    assert p.data[1 * 4 + 2] == 5.0
    p.data[12:16] = [1, 2, 3, 4]
    np.testing.assert_array_equal(p.params["b"], [1, 2, 3, 4])
    p.grads["E"][...] = 7.0
    assert np.all(p.grad[16:] == 7.0) and np.all(p.grad[:16] == 0)
    p.zero_grad()
    assert not p.grad.any() and np.shares_memory(p.grads["E"], p.grad)


def test_state_dict_is_a_copy_and_round_trips():
    p = Parameters({"W": (2, 3), "b": (3,)}, dtype=np.float64)
    p.data[...] = np.arange(9.0)
    state = p.state_dict()
    state["W"][0, 0] = 100.0
    assert p.params["W"][0, 0] == 0.0
    q = Parameters({"W": (2, 3), "b": (3,)}, dtype=np.float32)
    q.load_state_dict(p.state_dict())
    np.testing.assert_array_equal(q.data, np.arange(9.0))
    assert q.data.dtype == np.float32


def test_load_state_dict_errors_name_the_culprit():
    p = Parameters({"W": (2, 3), "b": (3,)})
    with pytest.raises(KeyError, match="'b'"):
        p.load_state_dict({"W": np.zeros((2, 3))})
    with pytest.raises(ValueError, match=r"'W' has shape \(3, 2\)"):
        p.load_state_dict({"W": np.zeros((3, 2)), "b": np.zeros(3)})
    with pytest.raises(KeyError, match="unexpected"):
        p.load_state_dict({"W": np.zeros((2, 3)), "b": np.zeros(3), "c": 1}, strict=True)
    p.load_state_dict({"W": np.ones((2, 3)), "b": np.ones(3), "c": 1})   # extras are fine by default
    assert np.all(p.data == 1)


def test_astype_copies():
    p = Parameters({"W": (2, 2)})
    p.data[...] = [1, 2, 3, 4]
    p.trainable = False
    q = p.astype(np.float64)
    assert q.data.dtype == np.float64 and q.trainable is False
    q.data[0] = 9
    assert p.data[0] == 1 and q.params["W"][0, 0] == 9


def test_initialisers():
    rng = np.random.default_rng(0)
    a = np.empty((200, 300))
    init_uniform_fan(a, 200, 300, rng)
    r = math.sqrt(6 / 500)
    assert np.abs(a).max() <= r and np.abs(a).max() > 0.99 * r
    assert abs(a.mean()) < 0.01 * r
    init_he_normal(a, 200, rng)
    assert abs(a.std() - math.sqrt(2 / 200)) < 0.01 * math.sqrt(2 / 200)
