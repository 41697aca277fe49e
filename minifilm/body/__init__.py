"""The body of a motion: which joint is the hips, the spine, the head, a collar, a hand, a foot,
found once per file, and retargeting onto another rig with it (docs/retargeting.md).

    from minifilm.body import load_rig, read_source, retarget_motion
    target = load_rig("100style")                    # or "bandai", "cmu", a BVH file
    motion, roles = read_source("walk_bandai.bvh")   # read once, its body found once
    result = retarget_motion(motion, target, roles)

The phases, the features, the viewer and the retargeting take what is found as given. Modules:

* read.py         -- a file read once and its body found once (``Body``), the readers of every command
* rig.py          -- the built-in skeleton its joint names fit; the phase recipe's rig of a humanoid
* humanoid.py     -- ``find_humanoid``: by names (by_names.py) checked against the hierarchy, else by
                     structure (by_structure.py), on tree.py's posed hierarchy, into parts.py's record
* roles.py        -- the same parts by joint name, as retargeting reads them (``Roles``, JSON maps)
* units.py        -- a file's length unit from its legs, a body's standing height
* target.py       -- a target rig: hierarchy, roles, units (``load_rig``; built-ins in builtin_rigs.py)
* pose.py         -- canonical rest poses, the transfer of world bone directions, chain spreading
* proportions.py  -- how a rig's foot lies flat; its legs' length (the root's scale)
* tips.py, feet.py, clearance.py -- toe tips near a contact, the floor and planted feet, toes in swing
* retarget_clip.py   -- one clip onto a rig (``retarget_motion``); retarget_batch.py: a data set's files

A run folder as a target, finetune clips and ``view --on`` are in minifilm/pipeline/run_rig.py.
"""
from minifilm.body.read import read_source
from minifilm.body.retarget_clip import retarget_file, retarget_motion
from minifilm.body.roles import RigError, Roles
from minifilm.body.target import BUILTIN_RIGS, Rig, builtin_rig, load_rig

__all__ = ["BUILTIN_RIGS", "Rig", "RigError", "Roles", "builtin_rig", "load_rig", "read_source", "retarget_file",
           "retarget_motion"]
