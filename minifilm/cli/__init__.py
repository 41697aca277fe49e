"""The ``minifilm`` command: one entry point, one subcommand per thing a user does.

    minifilm train        the main job: data -> phases -> dataset -> training -> generated motion
    minifilm phases       draw a BVH file's foot contacts and local phases (the paper's Figure 4)
    minifilm dataset      build (and cache) the training data of a folder of BVH files
    minifilm generate     generate motion with the released network or a trained run
    minifilm finetune     teach a trained run a new style from a short clip (Ψ only, Sec. 5.3.2)
    minifilm view         show BVH files: an animated GIF and an offline 3-D HTML player
    minifilm retarget     put motion of any humanoid rig onto another rig (100STYLE, Bandai, CMU, a run)
    minifilm table2       Table 2: parameter counts and run time of the seven comparison models
    minifilm compare      Figure 10 and the style metrics: train and compare the seven models
    minifilm gradcheck    check every backward pass against numerical gradients (the table)
    minifilm demo         steer a character live in the browser (the real-time controller)

Each subcommand is a module of this package with ``HELP`` (one line), ``add_arguments(parser)``
and ``run(args)``. Bad input (a missing file, a malformed BVH, a corrupt checkpoint, an argument
out of range) is reported as one line, ``error: ...``, with exit code 2; anything else is a bug
and keeps its traceback.
"""
from __future__ import annotations

import argparse
import codecs
import importlib
import os
import signal
import sys
import threading
from typing import Callable, Optional

from minifilm.errors import MissingDependencyError, OutputPathError  # (imports nothing: numpy stays unloaded)
from minifilm.parallel import ONE_BLAS_THREAD  # (nor does this)

#: name -> (module, one-line help, environment defaults set before the module is imported)
#: Training runs on one BLAS thread unless told otherwise: its matrices are small, a second thread
#: gained 10-25 % on an idle 2-core machine, and on a shared one made steps 3-25x slower
#: (benchmarks/README.md). So do the commands whose maps run in worker processes (dataset,
#: finetune's walks, compare's runs; their workers take one BLAS thread whatever this process has).
COMMANDS = {
    "train": ("minifilm.cli.train", "the main job: synthetic or your data -> trained model -> generated motion",
              ONE_BLAS_THREAD),
    "phases": ("minifilm.cli.phases", "draw a BVH file's contacts and local phases (Figure 4)", {}),
    "dataset": ("minifilm.cli.dataset", "build and cache the training data of BVH files", ONE_BLAS_THREAD),
    "generate": ("minifilm.cli.generate", "generate motion with the released network or a trained run", {}),
    "finetune": ("minifilm.cli.finetune", "teach a trained run a new style from a short clip (Ψ only)",
                 ONE_BLAS_THREAD),
    "view": ("minifilm.cli.view", "show BVH files as an animated GIF and an offline 3-D HTML player", {}),
    "retarget": ("minifilm.cli.retarget", "put motion of any humanoid rig onto another rig (100style, bandai, "
                 "cmu, a run, a BVH)", {}),
    # batch-1 timing on one BLAS thread, like a game loop: a matrix-vector product gains nothing
    # from threads, and on a busy machine threaded BLAS made it ~20x slower here
    "table2": ("minifilm.cli.table2", "Table 2: parameter counts and run time of the seven models", ONE_BLAS_THREAD),
    "compare": ("minifilm.cli.compare", "Figure 10 and style metrics: train and compare the seven models",
                ONE_BLAS_THREAD),
    # tiny arrays: threaded BLAS only adds overhead, and the check shares the machine
    "gradcheck": ("minifilm.cli.gradcheck", "check every backward pass against numerical gradients (the table)",
                  ONE_BLAS_THREAD),
    # a batch-1 frame loop, like table2's timing: one BLAS thread (see above)
    "demo": ("minifilm.cli.demo", "steer a character live in the browser (released network or a trained run)",
             ONE_BLAS_THREAD),
}

#: What a user can get wrong: these errors describe the input and are printed as one line.
#: Any OSError about a path (missing, unreadable, a name too long, a symlink loop, a read-only
#: file system, no space left) is the user's environment, not a bug; so is a missing optional
#: package or ffmpeg: the message says what to install.
INPUT_ERRORS = (OSError, OutputPathError, ValueError, MissingDependencyError)


class Parser(argparse.ArgumentParser):
    """argparse with a one-line error: the bad argument and how to see the options, not the
    whole usage block."""

    def error(self, message):
        self.exit(2, f"error: {self.prog}: {message} (see {self.prog} --help)\n")


def describe_error(e: BaseException) -> str:
    """One line for an input error: an OSError as 'path: reason' (not '[Errno 2] ...'), with any
    note added on the way up (e.g. which file a dataset was being built from)."""
    if isinstance(e, OSError) and e.filename is not None and e.strerror:
        text = f"{e.filename}: {e.strerror}"
    elif isinstance(e, UnicodeEncodeError) and _is_terminal_encoding(e.encoding):
        text = (f"this terminal's character encoding ({e.encoding}) cannot show {e.object[e.start:e.end]!r}, part of "
                "what minifilm had to print (a name, a path); use a UTF-8 terminal (LANG=C.UTF-8, or "
                "PYTHONIOENCODING=utf-8)")
    else:
        text = str(e) or type(e).__name__
    notes = " ".join(getattr(e, "__notes__", []))
    return " ".join(f"{text} {notes}".split())


def _is_terminal_encoding(encoding: str) -> bool:
    """Whether ``encoding`` is the one standard output or standard error writes in."""
    def name(enc):
        try:
            return codecs.lookup(enc).name
        except (LookupError, TypeError):
            return None
    return name(encoding) is not None and name(encoding) in (name(getattr(s, "encoding", None))
                                                             for s in (sys.stdout, sys.stderr))


def report_errors(main: Callable[[], Optional[int]]) -> None:
    """Call ``main()`` and exit with its code, or print ``error: <message>`` and exit 2 when it
    raises an input error (FileNotFoundError, a ValueError such as BVHError, CheckpointError, ...)."""
    try:
        code = main()
    except INPUT_ERRORS as e:
        _stopped(stop_behind(e))                 # a stop that this error only hid ends as a stop
        print(f"error: {describe_error(e)}", file=sys.stderr)
        sys.exit(2)
    except MemoryError:
        print("error: out of memory (the input asks for more than this machine has)", file=sys.stderr)
        sys.exit(1)
    except (KeyboardInterrupt, Terminated) as stop:
        _stopped(stop)
    sys.exit(code if isinstance(code, int) else 0)


def stop_behind(e: BaseException) -> Optional[BaseException]:
    """The KeyboardInterrupt or Terminated that ``e`` was raised while handling, if any: Ctrl-C cut
    a read short, closing the file then failed (EBADF), and the reader named the file as broken.
    What happened was the stop."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, (KeyboardInterrupt, Terminated)):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def _stopped(stop: Optional[BaseException]) -> None:
    """Exit as a stop (130 for Ctrl-C, 143 for SIGTERM, one line saying which); nothing for None."""
    if stop is None:
        return
    _quiet_teardown()
    interrupted = isinstance(stop, KeyboardInterrupt)
    print("interrupted" if interrupted else "terminated", file=sys.stderr)
    sys.exit(130 if interrupted else 143)


def _quiet_teardown() -> None:
    """After a stop, objects the interrupt left half-made (a ZipFile whose constructor was cut
    short, say) may fail in their ``__del__``; Python would print each as "Exception ignored" with a
    traceback under the one line that says what happened. Those are the stop's echo, not news."""
    sys.unraisablehook = lambda unraisable: None


def usage() -> str:
    width = max(len(n) for n in COMMANDS)
    lines = ["usage: minifilm COMMAND [options]   (minifilm COMMAND --help for its options)", "",
             "minifilm: local motion phases + FiLM style modelling (Mason, Starke, Komura 2022) in NumPy.", "",
             "commands:"]
    lines += [f"  {name:<{width}}  {text}" for name, (_, text, _) in COMMANDS.items()]
    return "\n".join(lines)


def main(argv=None) -> None:
    """The console entry point (``minifilm`` and ``python -m minifilm``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(usage())
        sys.exit(0 if argv else 2)
    name = argv[0]
    if name not in COMMANDS:
        print(f"minifilm: unknown command {name!r}\n\n{usage()}", file=sys.stderr)
        sys.exit(2)
    module_name, text, env = COMMANDS[name]
    for key, value in env.items():     # before numpy is imported (OpenBLAS reads them once)
        os.environ.setdefault(key, value)

    def command():
        # Imported only when chosen: a command may need an optional extra (matplotlib, the demo's
        # server) that the others do without, and `minifilm --help` stays instant. Inside
        # run_command: Ctrl-C while importing is a stop like any other (no traceback), and an
        # argument's type check may meet an OSError (a path name too long, a symlink loop) or
        # record an input.
        module = importlib.import_module(module_name)
        parser = Parser(prog=f"minifilm {name}", description=module.__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(parser)
        return module.run(parser.parse_args(argv[1:]))
    run_command(command)


def run_command(main: Callable[[], Optional[int]]) -> None:
    """:func:`report_errors` of ``main()`` as a command: the files it is given to read are recorded
    while it runs, so that none of its outputs replaces one (minifilm/files/output_targets.py), and
    Ctrl-C and SIGTERM end it by an exception, so what it was writing is cleaned up (a run being
    built, a temporary file) and an earlier run stays as it was (the demo sets its own handlers)."""
    previous = _install_stop_handlers()      # first: a stop while importing is a stop too

    def with_inputs():
        from minifilm.files import command_inputs   # here: it loads numpy, which must read the BLAS settings first
        with command_inputs():
            return main()
    try:
        report_errors(with_inputs)
    finally:
        for signum, handler in previous.items():
            if handler is not None:         # None: a handler not set from Python, nothing to restore
                signal.signal(signum, handler)


def _install_stop_handlers() -> dict:
    """Make Ctrl-C raise KeyboardInterrupt and SIGTERM raise :class:`Terminated`, whatever this
    process inherited; returns ``{signal: the handler it replaced}`` (empty when this is not the
    main thread, where Python cannot set handlers: a caller's thread keeps its own).

    SIGINT is set explicitly, not left to Python: a process started with SIGINT ignored (by a
    shell script's ``cmd &``, which runs without job control, or after ``trap '' INT``) keeps it
    ignored, Python then installs no KeyboardInterrupt handler, and Ctrl-C or ``kill -INT`` would
    be lost: ``train`` would run to its end and replace the earlier run. A user who sends SIGINT
    to a long command means to stop it."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {signal.SIGINT: signal.signal(signal.SIGINT, signal.default_int_handler),
            signal.SIGTERM: signal.signal(signal.SIGTERM, _terminate)}


def _terminate(signum, frame):
    raise Terminated()


class Terminated(BaseException):
    """SIGTERM, raised where the command is so that its cleanup runs (like KeyboardInterrupt)."""
