"""The body of a motion: which joint is the hips, the spine, the head, a collar, a hand, a foot.

Decided once per file, here, by names checked against the hierarchy's structure (else by the
structure alone); the phases, the features, the viewer and the retargeting take the answer as given.
"""
