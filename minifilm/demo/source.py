"""What drives the demo's characters: the released network or a trained run folder.

The two differ in the settings ``minifilm generate`` measured for them (its ``Source``):

* the authors' released network (``--params``): the 100STYLE skeleton, every frame put on it and
  the fitted pose fed back to the network (as the Unity demo feeds back its post-IK pose), and a
  per-style speed calibration (the network follows the user's trajectory only partly, so the
  commanded m/s is mapped to the command that makes it really move that fast);
* a run folder written by ``minifilm train`` (``--run``): its own skeleton, fit as an output
  post-process only, its position bias, start frames per style, and a speed calibration measured
  only with commands its data holds (``RUN_CALIBRATION_COMMANDS``, up to 4 m/s: a small model
  does not survive the 24 m/s the released network's calibration asks for).

Both turn the body towards the steered heading while walking (``runtime/heading.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Optional, Tuple

import numpy as np

from minifilm.features.layout import FeatureLayout
from minifilm.motion.motion import Motion
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.run_folder import RunFolder
from minifilm.runtime.adapted import with_adapters
from minifilm.runtime.calibration import CALIBRATION_COMMANDS, RUN_CALIBRATION_COMMANDS
from minifilm.runtime.heading import HeadingFollow
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.released import load_released
from minifilm.runtime.style_pack import load_pack, with_pack
from minifilm.runtime.style_library import StyleLibrary
from minifilm.synthetic.generator import rest_motion


@dataclass
class DemoSource:
    """network, layout, fps, styles and skeleton, plus how to drive them.

    feed_back_fit: with the skeleton fit on, feed the fitted pose back to the network.
    calibrate: map the user's m/s through a per-style speed calibration.
    calibration_commands: the commanded speeds (m/s) a calibration measures.
    starts: style -> (x (x_dim,), p (8,)) raw start frame; styles without one start from the mean pose.
    params: the released folder (None for a run).
    pack: a style pack folder whose styles join the released network's (its worker loads it too);
    pack_names: those styles' names.
    run_feed_speed: m/s of the perfect run fed as the trajectory input while Shift is held
        (``Controller.run_feed``): the released network runs only when shown a run; None: Shift
        is only a faster command.
    """

    name: str
    network: RuntimeNetwork
    layout: FeatureLayout
    fps: float
    library: StyleLibrary
    skeleton: Motion
    feed_back_fit: bool
    calibrate: bool
    options: dict = field(default_factory=dict)
    starts: Dict[str, Tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    params: Optional[Path] = None
    pack: Optional[Path] = None
    pack_names: Tuple[str, ...] = ()
    run_feed_speed: Optional[float] = None
    calibration_commands: Tuple[float, ...] = CALIBRATION_COMMANDS

    @classmethod
    def released(cls, params, calibrate: bool = True, pack=None) -> "DemoSource":
        rel = load_released(params)
        styles = load_pack(pack, film_dim=4 * rel.model.config.hidden, reserved=rel.styles,
                           network=rel.network) if pack else None
        name = f"released network ({Path(params).name})" + (f" with the style pack {Path(pack).name}" if pack else "")
        # a pack style's adapter acts only while that style is on (runtime/adapted.py)
        network, library = with_adapters(rel.network, with_pack(rel.styles, styles), styles.adapters if styles else {})
        return cls(name, network, FeatureLayout.for_skeleton(STYLE100), 60.0, library,
                   rest_motion(), feed_back_fit=True, calibrate=calibrate,
                   options={"heading_follow": HeadingFollow()}, params=Path(params), run_feed_speed=8.0,
                   pack=Path(pack) if pack else None, pack_names=tuple(styles.names) if styles else ())

    @classmethod
    def run_folder(cls, path, calibrate: bool = True) -> "DemoSource":
        run = RunFolder.load(path)
        network, library = run.adapted()
        return cls(f"trained run ({Path(path).name})", network, run.layout, run.fps, library,
                   run.template(), feed_back_fit=False, calibrate=calibrate,
                   options={"position_bias": run.position_bias, "heading_follow": HeadingFollow()},
                   starts=run.starts(), calibration_commands=RUN_CALIBRATION_COMMANDS)

    def default_style(self) -> str:
        return "Neutral" if "Neutral" in self.library else self.library.names[0]

    def contact_joints(self) -> list:
        """Exported-joint index of the right and left toe (the contact columns' order), or []."""
        names = list(self.layout.joint_names)
        for pair in (("RightToe", "LeftToe"), ("RightAnkle", "LeftAnkle"), ("RightFoot", "LeftFoot")):
            if all(n in names for n in pair):
                return [names.index(n) for n in pair]
        return []
