"""Retargeting: any humanoid clip onto any rig (docs/retargeting.md).

    from minifilm.rigs import load_rig, read_source, retarget_motion
    target = load_rig("100style")                    # or "bandai", "cmu", a BVH file
    motion, roles = read_source("walk_bandai.bvh")
    result = retarget_motion(motion, target, roles)

The roles of a rig's joints (hips, spine, neck, limbs) come from minifilm/body/roles.py, found
once per file; these modules take them as given. In the order the data flows through them:

* builtin_rigs.py -- the Bandai and CMU hierarchies (100STYLE's is minifilm/synthetic/body.py)
* rig.py         -- a target rig: hierarchy, roles, units (``load_rig``)
* pose.py        -- canonical rest poses, the transfer of world bone directions, chain spreading
* proportions.py -- how a rig's foot lies flat; its legs' length (the root's scale)
* tips.py        -- where a toe tip goes near a contact: heights the contact test needs, no slide
* feet.py        -- the floor, planted contacts, leg IK
* retarget_clip.py        -- one clip onto a rig (``retarget_motion``)
* batch.py       -- a data set's files onto one rig (``minifilm train --rig``)

A run folder as a target, finetune clips and ``view --on`` are in minifilm/pipeline/run_rig.py.
"""
from minifilm.body.read import read_source
from minifilm.body.roles import RigError, Roles
from minifilm.rigs.retarget_clip import retarget_file, retarget_motion
from minifilm.rigs.rig import BUILTIN_RIGS, Rig, builtin_rig, load_rig

__all__ = ["BUILTIN_RIGS", "Rig", "RigError", "Roles", "builtin_rig", "load_rig", "read_source", "retarget_file",
           "retarget_motion"]
