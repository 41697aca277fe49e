"""Worker processes (minifilm/processes.py): a worker's error raised again in the parent as itself,
the default number of workers, and the caller's script kept out of the workers' start."""
import sys
from multiprocessing import spawn as mp_spawn

import pytest

import minifilm.processes as processes
from minifilm.errors import DataError
from minifilm.motion.bvh import BVHError
from minifilm.processes import default_workers, error_reply, rebuilt_error


def raised(e: Exception) -> Exception:
    try:
        raise e
    except Exception as caught:       # noqa: BLE001
        caught.add_note("(while doing this)")
        return caught


@pytest.mark.parametrize("error", [ValueError("bad value"), DataError("a.bvh: frame 3: x[2] is nan"),
                                   BVHError("a.bvh", 12, "expected a number"),
                                   FileNotFoundError(2, "No such file or directory", "a.bvh"), KeyError("joint")],
                         ids=lambda e: type(e).__name__)
def test_an_error_comes_back_as_itself(error):
    sent = raised(error)
    back = rebuilt_error(error_reply(sent))
    assert type(back) is type(sent) and str(back) == str(sent) and back.args == sent.args
    assert back.__notes__ == ["(while doing this)"]
    assert getattr(back, "line", None) == getattr(sent, "line", None)              # a BVHError's own attributes
    assert getattr(back, "filename", None) == getattr(sent, "filename", None)


def test_a_class_that_is_not_builtin_or_minifilms_comes_back_as_one_line():
    class Strange(Exception):
        pass
    back = rebuilt_error(error_reply(raised(Strange("odd"))))
    assert type(back) is RuntimeError and str(back) == "Strange: odd"
    reply = error_reply(raised(ValueError("x")))
    for module, kind in [("os", "system"), ("builtins", "print"), ("minifilm" + ".missing", "X"), ("builtins", "a.b")]:
        assert type(rebuilt_error({**reply, "module": module, "kind": kind})) is RuntimeError


def test_default_workers_every_core_at_most_one_per_job(monkeypatch):
    monkeypatch.setattr(processes, "usable_cores", lambda: 4)
    assert [default_workers(n) for n in (0, 1, 3, 4, 100)] == [1, 1, 3, 4, 4]


def test_the_callers_script_is_hidden_while_a_worker_starts_and_put_back():
    main = sys.modules["__main__"]
    before = {k: main.__dict__[k] for k in ("__file__", "__spec__") if k in main.__dict__}
    with processes._main_module_hidden():
        assert getattr(main, "__file__", None) is None and getattr(main, "__spec__", None) is None
        prepared = mp_spawn.get_preparation_data("test")         # what a spawned worker is told to run
        assert "init_main_from_path" not in prepared and "init_main_from_name" not in prepared
    assert {k: main.__dict__[k] for k in ("__file__", "__spec__") if k in main.__dict__} == before


def test_how_a_worker_ended_is_said_in_words():
    from types import SimpleNamespace
    from minifilm.processes import how_it_ended

    def ended(code):
        return SimpleNamespace(join=lambda timeout=None: None, exitcode=code)
    assert how_it_ended(ended(-9)) == "was killed by SIGKILL"
    assert how_it_ended(ended(-15)) == "was killed by SIGTERM"
    assert how_it_ended(ended(3)) == "exited with code 3"
    assert how_it_ended(ended(None)) == "exited with code None"
    assert how_it_ended(ended(-200)) == "was killed by signal 200"
