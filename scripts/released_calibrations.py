"""Measure the speed calibration of every style of the authors' released network and write the file
the package ships (``minifilm/demo/shipped_calibrations/``), so that ``minifilm demo --params`` on
that network starts calibrated on a new machine and measures nothing while a page is open.

    python scripts/released_calibrations.py --params ../shared/data/released-lpn

The file is named by the calibration key (a hash of the network and of how the demo drives it,
``minifilm/demo/calibration_cache.py``); files of other keys in the folder are removed. Run it again
whenever ``CALIBRATION_VERSION`` changes or the controller's driving changes: a test measures some
styles anew and compares them with the file. About 2.5 s a style (4 minutes on two cores).
"""
from __future__ import annotations

import argparse
import time

from minifilm.demo.calibration_cache import SHIPPED, CalibrationCache
from minifilm.demo.calibrations import measure
from minifilm.demo.source import DemoSource


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--params", required=True, help="the released network's folder")
    args = ap.parse_args()
    source = DemoSource.released(args.params)
    SHIPPED.mkdir(exist_ok=True)
    table = CalibrationCache(source, where=SHIPPED, shipped=None, ignore_cached=True)
    started = time.perf_counter()
    for i, name in enumerate(source.library.names):
        table.put(name, measure(source, name))
        print(f"{i + 1:3d}/{len(source.library)} {name:<20s} {time.perf_counter() - started:6.0f} s", flush=True)
    for old in SHIPPED.glob("calibration-*.json"):
        if old != table.path:
            old.unlink()
    print(f"wrote {table.path}")


if __name__ == "__main__":
    main()
