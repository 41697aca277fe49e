"""The deep-learning kit, written from scratch. Knows nothing about motion.

The plain form of each piece comes first; where training runs a faster form, it lives beside it
in a ``fast_*`` module and is tested equal to the plain one.

    functional.py   forward/backward pairs (the maths of every layer)
    conv.py         conv1d (im2col, one matrix product) and max-pool, the layers of Ψ
    fast_conv.py    the same conv1d fast: reused buffers, or exactly through the FFT (what training runs)
    fast_linear.py  the linear backward with dW in a reused buffer (Ψ's dense layers)
    checks.py       shape checks that name the culprit
    workspaces.py      the fast forms' per-layer workspaces
    params.py       Parameters: named weights as views into one flat buffer; initialisers
    optim.py        Adam, the textbook update over flat buffers, skipping frozen sets
    fast_optim.py   the same Adam in place, chunk by chunk (what training uses)
    gradcheck.py    centred-difference gradient checks for any pair, block or network

The networks of the paper (minifilm/model/) are written with these pairs, grouped into blocks
(minifilm/model/blocks.py); import the modules you need, e.g. ``from minifilm.nn import functional as F``.
"""
