"""Memory a long command will need, estimated before it allocates anything.

A two-hour BVH file in ``view --html`` or ``generate --seconds 3600`` used to run until the
machine had no memory left (several GiB), and only then fail. These commands now estimate what
they need from sizes known up front -- frames x joints, from the BVH header or from ``--seconds``
-- and refuse at once, with the estimate, when it is over a limit: by default half of this
machine's memory (as ``dataset`` does), raised or lowered with ``--max-memory GB``.

The per-frame costs are measured -- the peak resident memory of the whole command (and Python's
``tracemalloc`` peak) for 5 s and for 200 s of motion, the slope per joint and frame -- then
rounded up.
"""
from __future__ import annotations

from typing import Optional

from minifilm.cli.args import positive
from minifilm.errors import InputError

#: bytes per joint and frame of ``generate``'s rollout and BVH (measured ~460 on the released network)
GENERATE_BYTES_PER_JOINT_FRAME = 500
#: bytes per joint and frame of ``view``'s tracks and HTML page (measured ~470 on a 200 s file)
VIEW_BYTES_PER_JOINT_FRAME = 550


def add_memory_option(ap) -> None:
    ap.add_argument("--max-memory", type=positive(float, 1e6), metavar="GB",
                    help="refuse before starting when the estimated memory is over this many GiB "
                         "(default: half of this machine's memory)")


def memory_limit(gib: Optional[float]) -> int:
    """The limit in bytes: ``gib`` GiB, or half of this machine's memory when None."""
    if gib is not None:
        return int(gib * 2**30)
    from minifilm.files.reading import memory_budget     # numpy: loaded only by the commands that check
    return memory_budget()


def check_memory(need: float, gib: Optional[float], what: str, smaller: str) -> None:
    """InputError when ``need`` bytes are over the limit (``--max-memory`` ``gib``); ``what``: what
    needs it, ``smaller``: how to ask for less."""
    limit = memory_limit(gib)
    if need <= limit:
        return
    whose = f"--max-memory {gib:g}" if gib is not None else "half of this machine's memory"
    raise InputError(f"{what} would need about {need / 2**30:.3g} GiB of memory, over the limit of "
                     f"{limit / 2**30:.3g} GiB ({whose}); {smaller}, or raise the limit with "
                     f"--max-memory {max(1, int(need / 2**30 + 1))} if this machine has the memory")
