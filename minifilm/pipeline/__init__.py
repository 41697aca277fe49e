"""The application layer: whole jobs built from the core (the main job, run folders).

    train_small.py   the main job: synthetic (or your) data -> phases -> dataset -> training ->
                     test table -> style library -> generated motion, into a run folder;
                     main_job() / new_trainer() / finish() are the pieces examples/train_small.py uses
    results.py       step 5: test table, loss curve, style library, generated motion, style
                     recognition, pictures (the viewer and evaluation load only there)
    run_folder.py    the run folder: what generate, finetune and the demo read back
"""
