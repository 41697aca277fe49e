"""The application layer: whole jobs built from the core (the main job, run folders).

    train_small.py   the main job: synthetic (or your) data -> phases -> dataset -> training ->
                     test table -> style library -> generated motion, into a run folder
    run_folder.py    the run folder: what generate, finetune and the demo read back
"""
