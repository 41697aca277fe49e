"""Labelling many files at once: the builder's per-file work (file_rows.label_file) in worker
processes, one BLAS thread each, so that building a data set of many files uses every core.

    parent (build.py: _build)                      worker w (spawned, minifilm/processes.py)
    survey, skeleton, frame rate, whole-file       the same settings, skeleton, rate and dtype
    splits; start W workers  --------------------> (one JSON text, given at its start)
    send file i (its entry, its split)  ---------> label_file(...) exactly as one process calls it
                                        <--------- its figures (JSON: rate, segments, each variant's
                                                   frames and splits) + its rows and clips (.npz bytes)
    collect file 0, 1, 2, ... in the files' order (_Builder.collect), whichever worker finishes first

Why the data set is the one of one process, bit for bit: a file's rows depend only on the file,
the settings, the skeleton and the frame rate (label_file reads nothing else), the worker runs the
same code on them, and the arrays come back as they were made (.npz, no conversion). The one
choice that depends on the files before -- whether a style still needs clips from a file that is
not of a clip gait (clip_fallback) -- is made by the parent when it collects: a worker makes such
clips whenever they may be needed and the parent drops them where one process would not have
made them. The frame rate, which one process takes from the first file it reads, comes from the
survey of the headers (the same number: both are 1 / the header's frame time).

Errors: a worker's error comes back as one JSON line and is raised as the same error (class,
message, notes: minifilm/processes.py's rebuilt_error) when its file's turn comes, so the builder
stops at the first bad file in the files' order and names it as one process does, whatever the
number of workers; no file after a failed one is started. A worker that dies raises WorkerDied.

Stopping: Ctrl-C or SIGTERM raise in the parent (the workers ignore SIGINT), which terminates the
workers on its way out of the ``with`` block; nothing is written before the whole data set is
made (the cache is written atomically after it). At most WINDOW files per worker are labelled
ahead of the oldest one not yet back, so a slow file cannot make the finished ones pile up.
"""
from __future__ import annotations

import io
import json
from dataclasses import asdict
from multiprocessing import connection
from pathlib import Path
from typing import List, Optional, Tuple

import numpy as np

from minifilm.dataset.file_rows import FileRows, Variant, label_file
from minifilm.dataset.manifest import MotionFile
from minifilm.dataset.settings import DatasetSettings
from minifilm.features.compute import FrameFeatures
from minifilm.motion.skeletons import Skeleton
from minifilm.processes import WithBytes, WorkerGroup, rebuilt_error, serve, spawn

#: files a worker may label ahead of the oldest file not yet back (per worker)
WINDOW = 4
#: frames of motion (mirrored copies counted) per worker by default: a worker's start -- a fresh
#: interpreter importing numpy, scipy.signal and the labelling code -- costs about a second of
#: CPU, about what labelling 1,000-2,000 frames costs (Bandai files, 30 fps); with less work than
#: this per worker, two workers took longer than one process (4 Bandai files, 278 frames, on a
#: busy 2-core machine: 2.2 s, against 0.8 s in one process)
FRAMES_PER_WORKER = 2000
#: the arrays of a segment's rows, as FrameFeatures holds them
ROW_ARRAYS = ("x", "p", "z", "frames")


# ---- a file's rows as bytes and back ------------------------------------------------------------
def pack(rows: FileRows) -> WithBytes:
    """FileRows as JSON figures + one .npz archive of its arrays (``{variant}/rows/{segment}/x``, ...)."""
    arrays, variants = {}, []
    for v, var in enumerate(rows.variants):
        for k, (_, ff) in enumerate(var.rows):
            arrays.update({f"{v}/rows/{k}/{name}": getattr(ff, name) for name in ROW_ARRAYS})
        arrays.update({f"{v}/clips/{k}": y for k, (_, y) in enumerate(var.clips)})
        variants.append({"mirrored": var.mirrored, "n_frames": var.n_frames,
                         "rows": [split for split, _ in var.rows], "clips": [split for split, _ in var.clips]})
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return WithBytes({"fps": rows.fps, "segments": rows.segments, "variants": variants}, buffer.getvalue())


def unpack(figures: dict, data: bytes) -> FileRows:
    """The FileRows that :func:`pack` was given (read with allow_pickle=False)."""
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        variants = [Variant(bool(m["mirrored"]), int(m["n_frames"]),
                            [(split, FrameFeatures(*(z[f"{v}/rows/{k}/{name}"] for name in ROW_ARRAYS)))
                             for k, split in enumerate(m["rows"])],
                            [(split, z[f"{v}/clips/{k}"]) for k, split in enumerate(m["clips"])])
                    for v, m in enumerate(figures["variants"])]
    return FileRows(float(figures["fps"]), [(int(a), int(b), str(s)) for a, b, s in figures["segments"]], variants)


# ---- the worker ---------------------------------------------------------------------------------
def worker(spec_text: str, conn) -> None:
    """The target of a worker process: settings, skeleton, frame rate and dtype from ``spec_text``
    (JSON), then label_file for every file it is sent."""
    def setup():
        spec = json.loads(spec_text)
        return (DatasetSettings(**spec["settings"]), Skeleton(**spec["skeleton"]), spec["fps"],
                np.dtype(spec["dtype"]))

    def job(state, m):
        settings, skeleton, fps, dtype = state
        f = m["file"]
        entry = MotionFile(Path(f["path"]), f["style"], f["gait"], f["start"], f["end"], f["mirror"])
        return pack(label_file(entry, settings, skeleton, fps, m["split"], m["clips"], dtype))
    serve(conn, setup, job)


# ---- the parent's side --------------------------------------------------------------------------
class LabellingWorkers(WorkerGroup):
    """``workers`` processes labelling ``jobs`` ([(MotionFile, its whole-file split or None)]);
    :meth:`next` gives their FileRows in the jobs' order. Use it as a context manager: the workers
    start when it is entered and are stopped when it is left, however it is left."""
    what = "dataset"

    def __init__(self, jobs: List[Tuple[MotionFile, Optional[str]]], settings: DatasetSettings, skeleton,
                 fps: float, dtype, workers: int):
        self.jobs, self.settings, self.workers = jobs, settings, workers
        self.spec = json.dumps({"settings": settings.to_dict(), "skeleton": asdict(skeleton), "fps": fps,
                                "dtype": np.dtype(dtype).str})
        self.procs, self.conns = [], []
        self.sent = self.collected = 0          # jobs sent / handed out by next(), in order
        self.busy, self.idle, self.replies = {}, [], {}   # {worker: job}, [worker], {job: reply}
        self.failed = False                     # a job failed: start no more

    def __enter__(self) -> "LabellingWorkers":
        self.procs, self.conns = spawn(self.workers, worker, (self.spec,), "minifilm-dataset-worker")
        try:
            for w in range(self.workers):
                self._reply(w, "starting")
        except BaseException as e:      # (a failed __enter__ gets no __exit__)
            self.__exit__(type(e), e, e.__traceback__)
            raise
        self.idle = list(range(self.workers))
        return self

    def next(self) -> FileRows:
        """The next file's rows, in the jobs' order; its error, raised as one process raises it."""
        i = self.collected
        while i not in self.replies:
            self._send()
            if not self.busy:       # (only if called again after an error or past the last file)
                raise RuntimeError(f"LabellingWorkers.next: file {i} was not sent to a worker")
            self._wait()
        reply = self.replies.pop(i)
        self.collected += 1
        if "error" in reply:
            raise rebuilt_error(reply)
        return unpack(reply["ok"], reply["data"])

    def _send(self) -> None:
        """Give idle workers the next files, up to WINDOW per worker ahead of the oldest not back."""
        st = self.settings
        while self.idle and self.sent < len(self.jobs) and not self.failed \
                and self.sent < self.collected + WINDOW * self.workers:
            w, (f, split) = self.idle.pop(0), self.jobs[self.sent]
            message = {"file": {"path": str(f.path), "style": f.style, "gait": f.gait, "start": f.start,
                                "end": f.end, "mirror": f.mirror},
                       "split": split, "clips": f.gait in st.clip_gaits or st.clip_fallback}
            self.send(w, message, f"labelling {f.path}")
            self.busy[w] = self.sent
            self.sent += 1

    def _wait(self) -> None:
        """Wait for a busy worker's reply (or its end) and keep it."""
        busy = list(self.busy)
        ready = connection.wait([self.conns[w] for w in busy] + [self.procs[w].sentinel for w in busy])
        for w in busy:
            if self.conns[w] in ready or self.procs[w].sentinel in ready:
                i = self.busy.pop(w)
                reply = self._reply(w, f"labelling {self.jobs[i][0].path}")
                self.failed |= "error" in reply
                self.replies[i] = reply
                self.idle.append(w)

    def _reply(self, w: int, doing: str) -> dict:
        """Worker w's next reply (its arrays, if it sends any, in 'data'), or WorkerDied."""
        reply = self.read(w, doing)
        if doing == "starting" and "error" in reply:
            raise rebuilt_error(reply)
        return reply
