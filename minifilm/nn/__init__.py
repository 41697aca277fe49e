"""The deep-learning kit, written from scratch. Knows nothing about motion.

    functional.py  forward/backward pairs (the maths of every layer)
    params.py      Parameters: named weights as views into one flat buffer; initialisers
    optim.py       Adam, the textbook update over flat buffers, skipping frozen sets
    fast_optim.py  the same Adam in place, chunk by chunk (what training uses)
    gradcheck.py   centred-difference gradient checks for any pair, block or network

The networks of the paper (minifilm/model/) are written with these pairs, grouped into blocks
(minifilm/model/blocks.py); import the modules you need, e.g. ``from minifilm.nn import functional as F``.
"""
