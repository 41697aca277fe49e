"""The labelling recipe of one motion file: foot contacts first, then the four local phases.

This is the one place that says how a file is labelled (Sec. 4.1; docs/original-code.md §2-§4),
so the dataset builder, the phase plot, the main job's phase check and the benchmarks all label
the same way:

    contacts = foot_contacts(toe-tip sensors)                  contacts.py  (Sec. 4.1.2)
    phases   = extract_local_phases(motion, contacts, sources)  local_phases.py (Sec. 4.1, Eq. 1)

with the phase sources of the style (a hopping style's lifted foot gets the contact-free PCA
source, :func:`~minifilm.phases.local_phases.default_sources`).

Any humanoid rig, not only the built-in skeletons: pass the
:class:`~minifilm.body.rig.HumanoidRig` its reader made (``load_for_phases`` in
minifilm/body/read.py reads a file in metres and finds its body once). Its contacts come from
``humanoid_contacts`` (contacts.py: its toe tips, with thresholds that hold on motion capture of
any source); the phases are the same recipe on its hips, wrists and toes. A built-in Skeleton
gives what it always gave, but where the paper's thresholds find next to no contact (``FEW_CONTACTS``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from minifilm.motion.motion import Motion
from minifilm.phases.contacts import foot_contacts, gait_contacts, humanoid_contacts
from minifilm.phases.local_phases import DEFAULT_SOURCES, LocalPhases, default_sources, extract_local_phases


#: a foot that steps is down on 15-60 % of a walk's or run's frames, and on all of a stand's; the
#: paper's thresholds finding a stepping foot down on fewer than this share have missed its stances
FEW_CONTACTS = 0.05


@dataclass
class Labels:
    """The labels of one motion.

    contacts (F, 2): 0/1 foot contacts, columns [right, left];
    phases: the four local phases [left hand, right hand, left foot, right foot] (phase,
        amplitude and the fitted sources for plotting);
    sources: the kind of source of each slot, 'pca' or 'contact';
    contact_rule: 'paper' (its thresholds), or 'gait' (``gait_contacts``': any humanoid rig, or a
        built-in skeleton's motion on which the paper's found next to no contact).
    """

    contacts: np.ndarray
    phases: LocalPhases
    sources: Tuple[str, ...] = DEFAULT_SOURCES
    contact_rule: str = "paper"

    @property
    def vectors(self) -> np.ndarray:
        """(F, 8) the network's phase input p, Eq. (1)."""
        return self.phases.vectors()

    def mirrored(self) -> "Labels":
        """The labels of the left-right mirrored motion (docs/original-code.md §1.3, §4.6): the two
        contact columns swap, and so do the left and right phase slots."""
        return Labels(self.contacts[:, ::-1].copy(), self.phases.mirrored(),
                      tuple(self.sources[i] for i in (1, 0, 3, 2)), self.contact_rule)


def label(motion: Motion, skeleton, style: Optional[str] = None,
          sources: Optional[Sequence[str]] = None, **fit_options) -> Labels:
    """Contacts and local phases of ``motion`` on ``skeleton``.

    ``skeleton``: a built-in Skeleton, or the HumanoidRig of the parts its reader found on
    ``motion`` (minifilm/body/read.py; taken as given: nothing is looked for here). ``style`` picks the phase sources (see
    ``default_sources``) unless ``sources`` names them; ``fit_options`` go to the sinusoid fit.
    Contacts use the skeleton's two toe-tip sensors with the floor height estimated from the file:
    the paper's thresholds on a built-in Skeleton (the gait rule when they find a stepping foot
    down on fewer than FEW_CONTACTS of the frames), ``humanoid_contacts``' on a HumanoidRig.
    """
    sources = default_sources(style) if sources is None else tuple(sources)
    humanoid = getattr(skeleton, "humanoid", None)        # a HumanoidRig carries the parts it was made of
    rule = "paper"
    if humanoid is not None:
        contacts, _ = humanoid_contacts(motion, humanoid)
        rule = "gait"
    else:
        positions, _ = motion.world()
        sensors = skeleton.contact_indices(motion)
        contacts = foot_contacts(positions[:, sensors], motion.fps)
        # the feet whose phases come from their contacts (a hopping style's lifted foot does not)
        stepping = [column for column, slot in ((0, 3), (1, 2)) if sources[slot] == "contact"]
        if any(contacts[:, c].mean() < FEW_CONTACTS for c in stepping):
            # PAPER: its thresholds (0.15 m/s, 1 cm) missed the stances (capture whose toes slide
            # or rest above the floor, a network's sliding walk): the gait rule of any rig instead
            contacts = gait_contacts(positions, sensors, skeleton.hips_index(motion), motion.fps)
            rule = "gait"
    return Labels(contacts, extract_local_phases(motion, skeleton, contacts, sources, **fit_options), sources, rule)
