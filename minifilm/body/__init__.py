"""The body of a motion: which joint is the hips, the spine, the head, a collar, a hand, a foot.

Decided once per file, here, by names checked against the hierarchy's structure (else by the
structure alone); the phases, the features, the viewer and the retargeting take the answer as
given. Modules, in the order a file's body is found:

* read.py         -- a file read once and its body found once (``Body``), the readers of every command
* rig.py          -- the built-in skeleton its joint names fit; the phase recipe's rig of a humanoid
* humanoid.py     -- ``find_humanoid``: by names (by_names.py), else by structure (by_structure.py),
                     on the posed hierarchy of tree.py, into the ``Humanoid`` record of parts.py
* roles.py        -- the same parts by joint name, as retargeting reads them (``Roles``, JSON maps)
* units.py        -- a file's length unit from its legs, a body's standing height
"""
