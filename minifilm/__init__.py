"""minifilm: local motion phases + FiLM style modelling in NumPy and SciPy.

A from-scratch implementation of Mason, Starke and Komura (2022), "Real-Time Style
Modelling of Human Locomotion via Feature-Wise Transformations and Local Motion Phases".

Subpackages:
    minifilm.nn      the deep-learning kit (forward/backward pairs, layers, Adam, gradcheck)
    minifilm.model   the paper's networks Omega, Phi, Psi and the losses
    minifilm.motion  BVH, kinematics, contacts, local phases, features, synthetic data
"""

__version__ = "0.1.0"
