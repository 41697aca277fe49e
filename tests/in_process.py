"""``minifilm ARGV`` run by ``cli.main`` in the test's own process: quicker than a child process,
and the exit code is the one the command line would give (tests/child_process.py runs a real one)."""
import pytest

from minifilm import cli


def minifilm_here(argv, capsys):
    """(exit code, what it printed: ``.out`` and ``.err``) of ``minifilm ARGV``; the items of argv
    may be paths or numbers (each is passed as its text)."""
    with pytest.raises(SystemExit) as stop:
        cli.main([str(a) for a in argv])
    return stop.value.code, capsys.readouterr()
