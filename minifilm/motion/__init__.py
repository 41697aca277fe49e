"""Motion-capture data: BVH, kinematics, contacts, phases, features. Knows nothing about networks."""
