"""minifilm: local motion phases + FiLM style modelling in NumPy and SciPy.

A from-scratch implementation of Mason, Starke and Komura (2022), "Real-Time Style
Modelling of Human Locomotion via Feature-Wise Transformations and Local Motion Phases".

Subpackages, in the order the data flows (imports point down this list; tests/test_import_rules.py):
    minifilm.nn          the deep-learning kit: forward/backward pairs, Parameters, Adam, gradcheck
    minifilm.motion      Motion, BVH read/write, kinematics, skeletons, skeleton fit, retargeting, foot IK
    minifilm.phases      foot contacts, phase sources, the sinusoid fit, local phases (Eq. 1)
    minifilm.features    the x / z / p / y layouts (Sec. 3.2) and their computation
    minifilm.synthetic   procedural stylised locomotion (the main job's default data)
    minifilm.dataset     manifests, splits, normalisation statistics, arrays, build, cache
    minifilm.model       the paper's networks Ω, Φ, Ψ, the style model (Eq. 4) and the losses (Eq. 5-7)
    minifilm.baselines   the comparison's PFNN / MANN / one-hot / residual-adapter variants (Sec. 5)
    minifilm.train       the trainer, style-balanced batches, checkpoints, fine-tuning
    minifilm.runtime     the batch-1 network, the controller, styles, the released network
    minifilm.viewer      GIF / HTML / MP4 pictures of motion (optional extra)
    minifilm.evaluation  Table 2, the comparison, metrics, style classifier, the gradient-check suite
    minifilm.pipeline    whole jobs: the main job, run folders, new styles
    minifilm.demo        the live browser demo (optional extra)
    minifilm.cli         the `minifilm` command
docs/equations.md says where each equation of the paper lives.
"""

__version__ = "0.1.0"
