"""The whole method, end to end, on data minifilm makes itself (about two minutes on a 2-core laptop).

    python examples/train_small.py                      # synthetic data, the settings below
    python examples/train_small.py --data DIR           # your own folder of <Style>_<Gait>.bvh files
    python examples/train_small.py --quick              # a smaller, faster run of the same steps
    python examples/train_small.py --epochs 10 --out runs/ten   # any setting below: --name value

The same job as ``minifilm train`` with its default settings, outputs and numbers; the settings
are the plain values below (``--name value`` on the command line replaces one, as nanoGPT's
configurator does; ``minifilm train --help`` says more about each). The package makes the data
before the training loop and the results after it (minifilm/pipeline/train_small.py):

 1. data:     8 synthetic styles x 6 gaits, written as 100STYLE-like BVH files;
 2. phases:   foot contacts, then local phases (Sec. 4.1, Eq. 1), checked against the true ones;
 3. dataset:  x / p / z rows and style clips y, split and normalised (Sec. 3.2);
 4. training: the small LPN + FiLM model, one epoch after another; each minibatch is one call of
              minifilm/train/trainer.py::Trainer.train_step: forward (Eq. 2-4), the losses
              (Eq. 5-7), every gradient by hand, Adam;
 5. results:  test MSE per style, one FiLM vector per style, one generated BVH per style along a
              figure-eight, how well a classifier recognises each style in it, a GIF and an HTML player.

Everything is written to the run folder runs/train_small/ (OUT), which ``minifilm generate --run``
and ``minifilm finetune --run`` read back.
"""
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

# ---- settings: the defaults of `minifilm train` (minifilm/pipeline/train_small.py::Settings says
# why each number is what it is); `--name value` on the command line replaces one
DATA = None                 # a folder of <Style>_<Gait>.bvh files or a CSV manifest; None: synthetic
OUT = "runs/train_small"    # the run folder
SEED = 0
QUICK = False               # a much smaller run of every step (seconds instead of minutes)
EPOCHS = 30
BATCH_SIZE = 32
LEARNING_RATE = 5e-4        # Adam's; the paper's 1e-4 is for its 40x larger network
CLIPS_PER_BATCH = 4         # style clips per minibatch, shared by its samples (None: one per sample)
STYLES = "Neutral,PendulumHands,LeftHop,Limp,HandsAbove,Crouched,Swimming,Drunk"   # synthetic
GAITS = "FW,BW,FR,SW,TR,ID" # synthetic gaits (idle files are skipped, as in 100STYLE)
SECONDS = 10.0              # synthetic seconds per style and gait
CLIP_SECONDS = 2.0          # the style clips y that Ψ reads (the paper: 4 s)
GENERATE_SECONDS = 10.0     # seconds of motion generated per style
SPLIT = "auto"              # your data: "files", "segments" or "auto" (Settings.split)
MIRROR = False              # your data: also train on every file's left/right mirror
FPS = None                  # your data: resample every file to this rate
RIG = None                  # your data: retarget every file onto this rig first
WORKERS = None              # processes sharing each minibatch (None: every core, one per clip at most)

# One BLAS thread, set before numpy loads: the matrices are small, and on a shared machine a second
# thread made steps slower (benchmarks/README.md), as for `minifilm train`.
for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(key, "1")

from minifilm.errors import InputError, MissingDependencyError, OutputPathError  # noqa: E402
from minifilm.pipeline.train_small import (Settings, finish, log_epoch, main_job,  # noqa: E402
                                           new_trainer, workers)


def override_settings(argv):
    """The settings above with ``--name value`` (or ``--name=value``; a bare ``--quick`` or
    ``--mirror`` is True) replacing NAME, read as the type of its default ("none" for None).
    -> (settings, the names given). InputError naming an unknown setting or an unreadable value."""
    settings = {name: value for name, value in globals().items() if name.isupper()}
    given, i = set(), 0
    while i < len(argv):
        word = argv[i]
        name, has_value, value = word[2:].partition("=")
        key = name.upper().replace("-", "_")
        if not word.startswith("--") or key not in settings:
            known = ", ".join("--" + k.lower().replace("_", "-") for k in settings)
            raise InputError(f"{word}: not a setting of examples/train_small.py (settings: {known})")
        if not has_value and isinstance(settings[key], bool):
            value = "true"
        elif not has_value:
            if i + 1 >= len(argv):
                raise InputError(f"{word}: give a value")
            i += 1
            value = argv[i]
        settings[key] = read_value(f"--{name}", value, settings[key])
        given.add(key)
        i += 1
    return settings, given


def read_value(word, value, default):
    """``value`` read as the type of ``default`` (a string when the default is None)."""
    if value.lower() == "none":
        return None
    if isinstance(default, bool):
        if value.lower() not in ("true", "false"):
            raise InputError(f"{word} {value}: true or false")
        return value.lower() == "true"
    try:
        return value if default is None or isinstance(default, str) else type(default)(value)
    except ValueError:
        kind = "a whole number" if isinstance(default, int) else "a number"
        raise InputError(f"{word} {value}: not {kind}") from None


#: setting -> (the field of Settings, how its value is read)
settings_fields = {"SEED": ("seed", int), "OUT": ("out", Path), "EPOCHS": ("epochs", int),
          "BATCH_SIZE": ("batch_size", int), "LEARNING_RATE": ("learning_rate", float),
          "CLIPS_PER_BATCH": ("clips_per_batch", int),
          "STYLES": ("styles", lambda v: tuple(v.split(","))),
          "GAITS": ("gaits", lambda v: tuple(v.split(","))),
          "SECONDS": ("seconds_per_clip", float), "CLIP_SECONDS": ("clip_seconds", float),
          "GENERATE_SECONDS": ("generate_seconds", float), "SPLIT": ("split", str),
          "MIRROR": ("mirror", bool), "FPS": ("fps", float), "RIG": ("rig", str),
          "WORKERS": ("workers", int)}


def job_settings(c: dict, given=()) -> Settings:
    """The main job's Settings from the plain values, as `minifilm train` makes them: QUICK
    shrinks the run, and a setting given on the command line wins over it."""
    def fields(names):
        out = {}
        for k in names:
            field, read = settings_fields[k]
            try:
                out[field] = None if c[k] is None else read(c[k])
            except ValueError:
                raise InputError(f"--{k.lower().replace('_', '-')} {c[k]}: not a number") from None
        return out
    for key in ("EPOCHS", "BATCH_SIZE", "SECONDS", "CLIP_SECONDS", "GENERATE_SECONDS"):
        if c[key] is None or c[key] <= 0:
            raise InputError(f"--{key.lower().replace('_', '-')} {c[key]}: give a positive number")
    if c["WORKERS"] is not None and not 1 <= c["WORKERS"] <= 1024:
        raise InputError(f"--workers {c['WORKERS']}: give a whole number from 1 to 1024")
    if c["CLIPS_PER_BATCH"] is not None and c["CLIPS_PER_BATCH"] >= c["BATCH_SIZE"]:
        c = dict(c, CLIPS_PER_BATCH=None)         # a clip per sample, as the paper
    s = Settings(**fields(settings_fields))
    if c["QUICK"]:
        s = replace(s.quick(), **fields(k for k in given if k in settings_fields))
    return s



def main(argv=None) -> None:
    c, given = override_settings(sys.argv[1:] if argv is None else argv)
    settings = job_settings(c, given)
    data = None if c["DATA"] is None else Path(c["DATA"])

    # ---- 1-3. data, local phases, dataset (the run is built beside OUT and swapped in at the end)
    with main_job(settings, data) as job:
        train_data, val_data = job.ds.train_data("train"), job.ds.train_data("val")

        # ---- 4. training: Ω, Φ, Ψ (minifilm/model/), the losses of Eq. (5)-(7), Adam
        trainer = new_trainer(job)                # the model, Adam, the random generator, the history
        with workers(trainer, settings) as pool:      # WORKERS processes share each minibatch
            for _ in range(settings.epochs):
                t0 = time.perf_counter()
                # one style per minibatch, 4 clips of that style; per minibatch Trainer.train_step:
                # model.forward (Eq. 4: Φ(x; Ω(p), Ψ(y))), trainer.losses (Eq. 5-7 and dL/dz),
                # model.backward (Ψ, Φ, Ω in reverse, by hand), a NaN check, adam.step()
                losses = trainer.train_epoch(train_data, pool)
                record = trainer.end_epoch(losses, val_data)     # validation MSE / BLL, checkpoint
                log_epoch(record, time.perf_counter() - t0)

        # ---- 5. results: test table, loss curve, styles.npz, generated BVH, style recognition, GIF, HTML
        finish(job, trainer)


if __name__ == "__main__":
    if "-h" in sys.argv[1:] or "--help" in sys.argv[1:]:
        print(__doc__)
        print("settings (--name value):")
        for name, value in override_settings([])[0].items():
            print(f"  --{name.lower().replace('_', '-'):<18} {value!r}")
        sys.exit(0)
    try:
        main()
    except (InputError, OutputPathError, MissingDependencyError) as error:   # one line, no traceback
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("interrupted: an earlier run in the run folder stays as it was", file=sys.stderr)
        sys.exit(130)
