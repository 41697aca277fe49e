"""Find a humanoid's parts in any skeleton: hips, spine, neck, head, arms and legs, by name or by shape.

``find_humanoid(motion)`` returns a :class:`Humanoid`: the joint index (into ``motion.names``) of
every part below. Two ways are tried, in order:

1. **Names** (:func:`humanoid_by_names`). Common conventions are read: sides as ``Left``/``Right``,
   ``l_``/``L_``/``l``/``L`` prefixes (``LHipJoint``, ``lShldr``), ``_l``/``_L``/``.L``/``Left``
   suffixes (``Shoulder_L``, ``thigh.L``), a separate ``L`` word (``Bip01 L Thigh``); namespaces
   (``mixamorig:``), ``joint_`` and ``Bip01`` prefixes are ignored; parts by their usual names
   (``UpLeg``/``UpperLeg``/``Thigh``/``Hip``, ``Leg``/``Knee``/``Shin``, ``Foot``/``Ankle``, ...).
2. **Structure** (:func:`humanoid_by_structure`), when the names do not give every part: from the
   pose (y up), the feet are the two lowest ends of the hierarchy (median over the clip) that lie
   far apart along the bones, the hips where their chains meet (or the first joint above that with
   a chain going up); the legs run from the hips to the feet, the head is the upward
   continuation, the arms the two long side chains off the spine (first frame). Left and right
   come from the facing (toes point forward, bent knees bulge forward): left is ``up x forward``.

Within a leg, the thigh and shin are the two consecutive bones with the largest summed length,
and the foot is what lies below the ankle; within an arm, the wrist is the first joint that
branches into fingers (else the two longest bones are upper arm and forearm). Joints that only
sit on their parent (zero offsets, e.g. the CMU ``LHipJoint``) are kept where names put them.

Both results are checked for a plausible human: legs reaching the floor below the hips, a foot
below each ankle, a head above the hips, hands that do not stand on the floor (a quadruped's front
legs would). Failing everything raises :class:`HumanoidError` (an InputError) naming what could
not be found, by names and by structure.
"""
from __future__ import annotations

from minifilm.body.by_names import humanoid_by_names, split_name
from minifilm.body.parts import ARM_ROLES, LEG_ROLES, LIMB_ROLES, Humanoid, HumanoidError
from minifilm.body.by_structure import humanoid_by_structure

__all__ = ["Humanoid", "HumanoidError", "find_humanoid", "humanoid_by_names", "humanoid_by_structure",
           "split_name", "ARM_ROLES", "LEG_ROLES", "LIMB_ROLES"]


def find_humanoid(motion) -> Humanoid:
    """The humanoid parts of ``motion``: by names, else by structure (module docstring).

    Raises HumanoidError naming the file and what neither way could find."""
    try:
        return humanoid_by_names(motion)
    except HumanoidError as by_names:
        try:
            return humanoid_by_structure(motion)
        except HumanoidError as by_structure:
            source = getattr(motion, "source", "<memory>")
            raise HumanoidError(f"{source}: not a humanoid skeleton that minifilm recognises. "
                                f"{by_names}. {by_structure}. Joints: {list(motion.names)[:12]}"
                                f"{' ...' if len(motion.names) > 12 else ''}") from None
