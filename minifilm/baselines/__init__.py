"""The comparison models of Sec. 5 (PFNN, MANN, LPN × one-hot, residual adapters, FiLM).

The code lives in one file per idea; this module gathers the public names:
    phase_function.py     the PFNN's cyclic Catmull-Rom phase function
    style_modulation.py   one-hot style input, residual adapters (full and CP-decomposed)
    expert_net.py         the synthesis network without FiLM
    variants.py           VARIANTS, build_variant, parameter counts (Table 2)
"""
from minifilm.baselines.phase_function import PhaseFunction, catmull_rom_weights  # noqa: F401
from minifilm.baselines.style_modulation import CPResidualAdapter, OneHotShift, ResidualAdapter  # noqa: F401
from minifilm.baselines.variants import (VARIANTS, LPNFilm, VariantModel, backbone_config,  # noqa: F401
                                     build_variant, variant_parameter_counts, variant_shapes)
