"""The released network's speed calibrations that come with the package
(minifilm/demo/shipped_calibrations/, written by scripts/released_calibrations.py): they are found
for the released network as the demo drives it, cover every style, and are what a measurement
made now gives: a change to the runtime, the controller's options or the measurement that would
make them stale fails here (then run the script again)."""
import numpy as np
import pytest

from demo_helpers import released_source  # noqa: F401  (fixture)
from minifilm.demo.calibration_cache import SHIPPED, CalibrationCache, calibration_key
from minifilm.demo.calibrations import measure

#: m/s: generous. Another CPU's sums differ in their last bits; the whole network in float64
#: instead of float32 moves Neutral's speeds by 1.5e-7 m/s (the walks do not amplify rounding),
#: while a stale table differs by far more (a changed option or step)
SPEED_TOLERANCE = 0.02


def test_the_shipped_file_is_the_released_networks_and_the_only_one(released_source):
    files = sorted(p.name for p in SHIPPED.glob("*.json"))
    assert files == [f"calibration-{calibration_key(released_source)}.json"], \
        "the shipped calibrations are not those of the released network as the demo drives it: " \
        "run scripts/released_calibrations.py"


def test_every_released_style_is_known_from_the_package(released_source, tmp_path):
    known = CalibrationCache(released_source, where=tmp_path).load()
    assert sorted(known) == sorted(released_source.library.names)
    assert CalibrationCache(released_source, where=tmp_path, shipped=None).load() == {}


@pytest.mark.parametrize("name", ["Neutral", "Zombie"])
def test_the_shipped_calibration_is_what_a_measurement_gives_now(released_source, tmp_path, name):
    shipped = CalibrationCache(released_source, where=tmp_path).load()[name]
    now = measure(released_source, name)
    np.testing.assert_array_equal(shipped.commanded, now.commanded)
    np.testing.assert_allclose(shipped.achieved, now.achieved, rtol=0, atol=SPEED_TOLERANCE)
