"""Make the README's animations: generated styles of the main job's model and of the released network.

    python scripts/readme_gifs.py --run runs/train_small --params ../shared/data/released-lpn

Writes docs/img/styles_synthetic.gif (every style of a run folder written by ``minifilm train``)
and docs/img/styles_released.gif (six styles of the authors' released network), each character
walking a figure-eight at 1.3 m/s from its own start, drawn with minifilm's viewer. The sizes are
kept small (12 fps, small panels, 4 s) so the README stays light.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from minifilm.features.layout import FeatureLayout
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.calibration import PerCharacterCalibration, calibrate_speed
from minifilm.runtime.control import figure_eight
from minifilm.runtime.controller import Controller
from minifilm.runtime.released import load_released
from minifilm.synthetic.generator import rest_motion
from minifilm.viewer.builders import tracks_from_rollout
from minifilm.viewer.gif import write_gif

ROOT = Path(__file__).resolve().parents[1]
RELEASED_STYLES = ("Neutral", "Zombie", "Old", "Aeroplane", "Strutting", "Penguin")


def toes_of(layout):
    return [layout.joint_names.index(t) for t in ("RightToe", "LeftToe")]


def synthetic(run_dir: Path, out: Path, seconds: float) -> None:
    run = RunFolder.load(run_dir)
    library = run.styles()
    names = [n for n in library.names if n in run.starts()]
    x0, p0 = run.start_states(names)
    n = int(round(seconds * run.fps))
    r = run.controller().run([figure_eight(seconds) for _ in names], n, np.stack([library[s] for s in names]),
                             phases=p0, start_x=x0)
    tracks = tracks_from_rollout(r, run.layout.parents, names, run.layout.joint_names, toes_of(run.layout))
    write_gif(tracks, out, every=5, size=(120, 150), columns=4)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB)")


def released(params: Path, out: Path, seconds: float) -> None:
    rel = load_released(params)
    layout = FeatureLayout.for_skeleton(STYLE100)
    names = list(RELEASED_STYLES)
    films = np.stack([rel.styles[s] for s in names])
    ctl = Controller(rel.network, layout, skeleton=Controller.skeleton_for(layout, rest_motion()), feed_back_fit=True)
    cal = PerCharacterCalibration([calibrate_speed(Controller(rel.network, layout), f, directions=(0.0,)) for f in films])
    n = int(round(seconds * 60))
    r = ctl.run([figure_eight(seconds) for _ in names], n, films, calibration=cal)
    # the first second starts from the mean pose: show the motion after it
    tracks = tracks_from_rollout(r, layout.parents, names, layout.joint_names, toes_of(layout), start=60)
    write_gif(tracks, out, every=5, size=(120, 150), columns=3)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB)")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, default=Path("runs/train_small"), help="a run folder of minifilm train")
    ap.add_argument("--params", type=Path, default=ROOT.parent / "shared" / "data" / "released-lpn")
    ap.add_argument("--seconds", type=float, default=4.0)
    a = ap.parse_args()
    img = ROOT / "docs" / "img"
    synthetic(a.run, img / "styles_synthetic.gif", a.seconds)
    released(a.params, img / "styles_released.gif", a.seconds + 1.0)


if __name__ == "__main__":
    main()
