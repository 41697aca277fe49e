"""The comparison models of Sec. 5 (Table 2): PFNN, MANN and LPN backbones × one-hot, residual
adapters and FiLM. Nothing in the core imports this package; it builds on minifilm.model.

    phase_function.py     the PFNN's cyclic Catmull-Rom phase function
    style_modulation.py   one-hot style input, residual adapters (full and CP-decomposed)
    expert_net.py         the synthesis network without FiLM
    variants.py           VARIANTS, build_variant, parameter counts (Table 2)
    variant_data.py       each backbone's gate input and output columns, from the LPN's data
    runtime.py            every variant through the one inference path and the controller
"""
