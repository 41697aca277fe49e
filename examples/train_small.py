"""The whole method, end to end, on data minifilm makes itself (a couple of minutes on a 2-core laptop).

    python examples/train_small.py                      # synthetic data, default settings
    python examples/train_small.py --data DIR           # your own folder of <Style>_<Gait>.bvh files
    python examples/train_small.py --quick              # a smaller, faster run of the same steps

This is the same job as ``minifilm train`` (and takes the same options). The steps, each a function
you can call on its own, are in ``minifilm/pipeline/train_small.py``:

 1. data:     ``make_synthetic`` writes 8 synthetic styles x 6 gaits as 100STYLE-like BVH files;
 2. phases:   ``phase_accuracy`` labels them (``minifilm.phases.label``: foot contacts, then local
              phases, Sec. 4.1) and measures the phases against the generator's true ones;
 3. dataset:  ``minifilm.dataset.build.build_dataset`` turns the files into x / p / z rows and style
              clips, splits and normalises them (Sec. 3.2);
 4. training: ``train`` fits a small LPN + FiLM model (Eq. 1-7) with style-balanced minibatches;
 5. results:  ``test_table`` (test MSE per style), ``save_loss_curve``, ``style_library`` (one FiLM
              vector per style, Sec. 4.4) and ``generate_per_style`` (one BVH per style from the
              autoregressive runtime along a figure-eight).

Everything is written to the run folder runs/train_small/ (--out), which ``minifilm generate --run``
and ``minifilm finetune --run`` read back.
"""
import sys

from minifilm.cli import main

if __name__ == "__main__":
    main(["train"] + sys.argv[1:])
