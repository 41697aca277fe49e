"""What every fuzz case asserts: a correct result or one clear error, nothing else.

``outcome(call, allowed, mentions)`` runs ``call()`` while tracemalloc (which numpy reports its
buffers to) records the peak memory, and checks that

* it returned, or raised one of the ``allowed`` exception types -- anything else (IndexError,
  ZeroDivisionError, numpy's LinAlgError, ...) propagates and fails the test with its traceback;
* an error's message is one non-empty line that contains every string in ``mentions`` (the file
  or argument it is about);
* the peak stayed under 1 GiB, and the case's own CPU time under 30 s: every case here takes well
  under a second, so 30 s of this process's CPU (not wall time, which other jobs stretch) means
  a loop that a hostile input made run away.
"""
import time
import tracemalloc

MAX_BYTES = 1 << 30
MAX_SECONDS = 30.0


def outcome(call, allowed, mentions=()):
    """(result, None) or (None, error); see the module docstring."""
    tracemalloc.start()
    t0 = time.process_time()
    result, error = None, None
    try:
        result = call()
    except allowed as e:
        error = e
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert peak < MAX_BYTES, f"peak memory {peak / 2**20:.0f} MiB"
    assert time.process_time() - t0 < MAX_SECONDS, "a runaway: 30 s of CPU"
    if error is not None:
        text = str(error)
        assert text.strip() and "\n" not in text, f"not one line: {text!r}"
        for m in mentions:
            assert str(m) in text, f"{text!r} does not name {m!r}"
    return result, error
