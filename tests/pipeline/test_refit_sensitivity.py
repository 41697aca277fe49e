"""Why a re-fitted FiLM vector can be far from the true one and still act like it
(minifilm/pipeline/refit_released.py): the Jacobian's gram by differences, and the share of an
error that lies in the directions the output sees."""
import numpy as np

from minifilm.pipeline.refit_released import jacobian_gram, sensitivity


class LinearRows:
    """predict(film, idx) = A[idx] @ film: a known Jacobian."""

    def __init__(self, A):
        self.A = A

    def predict(self, film, idx):
        return np.einsum("rzd,d->rz", self.A[idx], film)


def test_the_gram_of_a_linear_map_is_its_jacobian_squared():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(5, 3, 4))
    idx = np.array([0, 2, 4])
    gram = jacobian_gram(LinearRows(A), rng.normal(size=4), idx)
    J = A[idx].reshape(-1, 4)
    np.testing.assert_allclose(gram, J.T @ J / J.shape[0], rtol=1e-8, atol=1e-10)


def test_an_error_in_invisible_directions_is_counted_as_such():
    gram = np.diag([100.0, 10.0] + [1e-6] * 8)             # two directions carry the output
    hidden = np.zeros(10)
    hidden[5] = 1.0                                        # an error the output barely sees
    visible = np.zeros(10)
    visible[0] = 1.0
    s = sensitivity(gram, hidden, visible)
    assert s["k90"] == 1 and s["k99"] == 2 and s["dims"] == 10
    assert s["error_share_in_k99"] < 1e-12
    assert s["gain_error"] < 1e-2 < s["gain_other"] == 10.0
    assert sensitivity(gram, visible + 0.1 * hidden, hidden)["error_share_in_k99"] > 0.98
