"""A run folder: everything a trained model needs to generate motion, in one self-contained folder.

``minifilm train`` writes one and ``minifilm generate --run``, ``minifilm finetune --run`` and the
demo read it, from any working directory:

    run.json       what the folder holds: layout, frame rate, skeleton, runtime settings
    model.npz      the checkpoint: Ω, Φ, Ψ, optimiser state, normalisation statistics (.npz + JSON)
    styles.npz     the style library: one FiLM vector per style (Sec. 4.4)
    starts.npz     per style, a raw input frame x and its phases p from the style's own data, where
                   a generated motion starts (mid-stride rather than the data's mean pose)
    skeleton.bvh   one frame of the source skeleton: the BVH files are written on it
    adapters.npz, adapters.json   only when finetune taught a style an adapter of its own
                   (minifilm/runtime/adapter_file.py; applied only while that style is on)

run.json, styles.npz and starts.npz carry the run's id, and run.json a fingerprint of model.npz,
so a file of another run put into the folder is named as such (minifilm/pipeline/run_identity.py).

Nothing here is pickled; every array file loads with ``allow_pickle=False``.

``run.json`` is what makes a folder a run: it is written last (:meth:`RunFolder.commit`), after
every other file. ``minifilm train`` builds a run in a new folder beside the old one and swaps it in
whole when it is complete, holding a lock on the folder meanwhile (``minifilm.pipeline.train_small.run``),
so a training stopped midway leaves the earlier run as it was, never something that looks like a run
but is not one; ``minifilm finetune`` holds the same lock while it adds a style.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from minifilm.dataset.stats import NormStats
from minifilm.errors import InputError, check_fps
from minifilm.features.layout import FeatureLayout
from minifilm.files import (MAX_JSON_BYTES, Member, atomic_savez, atomic_write_text, check_name, check_regular, few,
                            note_input, parse_json, read_json, read_npz, read_npz_member)
from minifilm.pipeline.run_identity import (CHECKPOINT, RUN_ID, checkpoint_fingerprint, describe_foreign,
                                            foreign_files, new_run_id)
from minifilm.files.state import RUN_MARKER, RUN_STATE, is_run_entry  # noqa: F401  (is_run_entry: re-exported)
from minifilm.motion.bvh import read_bvh
from minifilm.motion.bvh_write import write_bvh
from minifilm.motion.motion import Motion
from minifilm.runtime.adapted import with_adapters
from minifilm.runtime.adapter_file import read_adapters
from minifilm.runtime.controller import Controller
from minifilm.runtime.network import RuntimeNetwork
from minifilm.runtime.style_library import StyleLibrary
from minifilm.train.checkpoint import CheckpointError, build_style_model, load_checkpoint, load_model_arrays

FORMAT = "minifilm-run-1"
MANIFEST = RUN_MARKER
#: every name a run folder holds (model-<NAME>.npz: a fine-tuned style's checkpoint): a folder with
#: anything else in it is not replaced by a new run; no output of another command replaces them
#: (minifilm/files/state.py, where they are listed once)
RUN_ENTRIES = set(RUN_STATE)


class RunFolderError(InputError):
    """A folder is not a minifilm run folder, or one of its files is missing or broken."""


@dataclass
class RunFolder:
    """A run folder on disk (see the module docstring); arrays are read on demand."""

    path: Path
    layout: FeatureLayout
    fps: float
    skeleton_name: str
    bvh_scale: float
    position_bias: float
    run_id: Optional[str] = None          # None: a run written before runs had ids
    checkpoint_id: Optional[str] = None   # model.npz's fingerprint (run_identity.checkpoint_fingerprint)

    # ---- writing ----------------------------------------------------------------------------
    @classmethod
    def prepare(cls, path, layout: FeatureLayout, fps: float, skeleton_name: str, bvh_scale: float,
                template: Motion, position_bias: float) -> "RunFolder":
        """Write skeleton.bvh (one frame of ``template``) into ``path``; the folder becomes a run
        when :meth:`commit` writes run.json, after everything else."""
        path = Path(path)
        write_bvh(template.slice(0, 1), path / "skeleton.bvh", scale=bvh_scale)
        return cls(path, layout, float(fps), skeleton_name, float(bvh_scale), float(position_bias), new_run_id())

    def commit(self) -> Path:
        """Write run.json: the folder is a complete run from now on (its checkpoint written)."""
        meta, _ = load_checkpoint(self.path / "model.npz")
        self.checkpoint_id = checkpoint_fingerprint(meta)
        manifest = {"format": FORMAT, "layout": self.layout.to_dict(), "fps": self.fps,
                    "skeleton": self.skeleton_name, "bvh_scale": self.bvh_scale,
                    "position_bias": self.position_bias, RUN_ID: self.run_id, CHECKPOINT: self.checkpoint_id}
        return atomic_write_text(self.path / MANIFEST, json.dumps(manifest, indent=1) + "\n")

    def save_starts(self, starts: Dict[str, Tuple[np.ndarray, np.ndarray]]) -> Path:
        """Per style, the raw input frame x (x_dim,) and phases p (8,) a rollout starts from."""
        names = list(starts)
        x = np.stack([np.asarray(starts[n][0], np.float64) for n in names]) if names else np.zeros((0, self.layout.x_dim))
        p = np.stack([np.asarray(starts[n][1], np.float64) for n in names]) if names else np.zeros((0, 8))
        arrays = {"names": np.array(names, dtype=str), "x": x, "p": p}
        if self.run_id is not None:
            arrays["run_id"] = np.array(self.run_id)
        return atomic_savez(self.path / "starts.npz", arrays)

    def save_styles(self, library: StyleLibrary) -> Path:
        """Write the style library as the run's styles.npz, marked with the run's id."""
        library.run_id = self.run_id
        library.save(self.path / "styles.npz")
        return self.path / "styles.npz"

    # ---- reading ----------------------------------------------------------------------------
    @classmethod
    def load(cls, path) -> "RunFolder":
        """Open a run folder; RunFolderError naming the folder and what is wrong otherwise."""
        path = Path(path)
        if not path.is_dir():
            raise RunFolderError(f"run folder {path}: no such folder")
        manifest = path / MANIFEST
        if not os.path.lexists(manifest):
            raise RunFolderError(f"run folder {path}: no {MANIFEST} (not a folder written by minifilm train)")
        meta = read_json(note_input(manifest), f"run folder {path}:", RunFolderError)
        try:
            if not isinstance(meta, dict):
                raise ValueError(f"a {type(meta).__name__}, expected an object")
            if meta.get("format") != FORMAT:
                raise ValueError(f"format {meta.get('format')!r}, expected {FORMAT!r}")
            for key in ("fps", "bvh_scale", "position_bias"):     # JSON's true is no number here
                if key in meta and (isinstance(meta[key], bool) or not isinstance(meta[key], (int, float))):
                    raise ValueError(f"{key} {meta[key]!r}: expected a number")
            fps = check_fps(meta["fps"], "fps")
            check_name(meta["skeleton"], "skeleton", ValueError)
            bvh_scale, bias = float(meta["bvh_scale"]), float(meta.get("position_bias", 0.75))
            if not (math.isfinite(bvh_scale) and bvh_scale > 0):
                raise ValueError(f"bvh_scale {bvh_scale}: must be a positive number")
            if not (math.isfinite(bias) and 0.0 < bias <= 100.0):   # an exponent of the trajectory blend
                raise ValueError(f"position_bias {bias}: must be a positive exponent (at most 100)")
            ids = [meta.get(key) for key in (RUN_ID, CHECKPOINT)]
            for key, value in zip((RUN_ID, CHECKPOINT), ids):
                if value is not None and not (isinstance(value, str) and value.isalnum() and len(value) <= 64):
                    raise ValueError(f"{key} {value!r}: expected a word of letters and digits")
            return cls(path, FeatureLayout.from_dict(meta["layout"]), fps, str(meta["skeleton"]), bvh_scale, bias,
                       *ids)
        except (ValueError, KeyError, TypeError, AttributeError) as e:
            raise RunFolderError(f"run folder {path}: {MANIFEST} is not valid ({e})") from None

    def _file(self, name: str) -> Path:
        p = self.path / name
        if not os.path.lexists(p):
            raise RunFolderError(f"run folder {self.path}: missing {name}")
        check_regular(p, f"run folder {self.path}:", RunFolderError)
        return p

    @property
    def checkpoint(self) -> Path:
        return note_input(self._file("model.npz"))     # read, never written by a command that reads it

    def model_and_stats(self):
        """(StyleModel with its trained weights, NormStats) from model.npz."""
        meta, arrays = load_checkpoint(self.checkpoint)
        try:
            model = build_style_model(meta)
            stats = NormStats.from_arrays(arrays, "stats.")
        except (KeyError, ValueError, TypeError, AttributeError) as e:
            raise CheckpointError(f"checkpoint {self.checkpoint}: bad configuration or statistics "
                                  f"({type(e).__name__}: {e})") from None
        load_model_arrays(model, arrays, self.checkpoint)
        self.check_checkpoint_belongs(meta)      # a readable checkpoint, but is it this run's?
        return model, stats

    def film_dim(self) -> int:
        """The length of the run's FiLM vectors (4 * hidden), from the checkpoint's configuration."""
        meta, _ = load_checkpoint(self.checkpoint)
        try:
            dim = int(meta["model_config"]["hidden"]) * 4
        except (KeyError, TypeError, ValueError):
            raise CheckpointError(f"checkpoint {self.checkpoint}: no model configuration") from None
        self.check_checkpoint_belongs(meta)
        return dim

    def styles(self, film_dim: Optional[int] = None) -> StyleLibrary:
        """The style library; ``film_dim`` (default: read from the checkpoint) is the width it
        must have, so a library of another run is an error here rather than a broadcast error
        in the middle of a rollout."""
        dim = self.film_dim() if film_dim is None else film_dim
        library = StyleLibrary.load(self._file("styles.npz"), dim=dim)
        self.check_files_belong()
        starts = self._member_names("starts.npz")
        if starts and not set(starts) & set(library.names):
            raise RunFolderError(f"run folder {self.path}: styles.npz is another run's style library: none of its "
                                 f"{len(library)} styles ({few(library.names)}) has a start frame in starts.npz "
                                 f"({few(starts)}), which minifilm train and finetune write for each style; put "
                                 "back this run's own styles.npz")
        return library

    def starts(self) -> Dict[str, Tuple[np.ndarray, np.ndarray]]:
        """style -> (x (x_dim,), p (8,)); empty when the folder has no starts.npz."""
        path = self.path / "starts.npz"
        if not os.path.lexists(path):
            return {}
        where = f"run folder {self.path}: starts.npz"
        self.check_files_belong()
        members = {"names": Member("U", ("S",)), "x": Member("f", ("S", self.layout.x_dim)),
                   "p": Member("f", ("S", 8)), RUN_ID: Member("U", (), optional=True)}
        d = read_npz(path, f"run folder {self.path}: start frames", RunFolderError, members=members)
        names, x, p = d["names"], d["x"].astype(np.float64), d["p"].astype(np.float64)
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(p))):
            raise RunFolderError(f"{where}: non-finite values")
        for i, n in enumerate(names.tolist()):
            check_name(n, f"{where}: style {i}", RunFolderError)
        return {str(n): (x[i], p[i]) for i, n in enumerate(names.tolist())}

    # ---- belonging together (minifilm/pipeline/run_identity.py) -------------------------------
    def _member(self, name: str, member: str, expected: Member):
        """The array ``member`` of the folder's archive ``name`` (``expected`` of it), or None when
        there is none or it cannot be read (the archive's own reader then says what is wrong)."""
        path = self.path / name
        if not os.path.lexists(path):
            return None
        try:
            return read_npz_member(path, member, name, RunFolderError, expected, MAX_JSON_BYTES)
        except (InputError, OSError):
            return None

    def _member_id(self, name: str) -> Optional[str]:
        value = self._member(name, RUN_ID, Member("U", ()))
        return None if value is None else str(value)

    def _member_names(self, name: str) -> list:
        value = self._member(name, "names", Member("U", (None,)))
        return [] if value is None else value.tolist()

    def file_ids(self) -> Dict[str, Optional[str]]:
        """file -> the run id it carries (None: none, as in runs written before ids existed);
        model.npz carries run.json's when its fingerprint is the one run.json recorded."""
        ids = {MANIFEST: self.run_id, "styles.npz": self._member_id("styles.npz"),
               "starts.npz": self._member_id("starts.npz")}
        if self.checkpoint_id is not None:
            meta = self._checkpoint_meta()
            if meta is not None and checkpoint_fingerprint(meta) == self.checkpoint_id:
                ids["model.npz"] = self.run_id
        return ids

    def _checkpoint_differs(self) -> bool:
        """Whether model.npz is known not to be the checkpoint run.json recorded."""
        if self.checkpoint_id is None:
            return False
        meta = self._checkpoint_meta()
        return meta is not None and checkpoint_fingerprint(meta) != self.checkpoint_id

    def _checkpoint_meta(self) -> Optional[dict]:
        """model.npz's configuration (its small meta.json member alone), or None when unreadable."""
        try:
            text = read_npz_member(self.path / "model.npz", "meta.json", "checkpoint", RunFolderError, Member("U", ()),
                                   MAX_JSON_BYTES)
            meta = None if text is None else parse_json(str(text), "checkpoint meta.json", RunFolderError)
        except (InputError, OSError):
            return None
        return meta if isinstance(meta, dict) else None

    def check_files_belong(self) -> None:
        """RunFolderError naming the file of another run when run.json, styles.npz and starts.npz
        do not all carry the same run id."""
        ids = self.file_ids()
        foreign = foreign_files(ids)
        if foreign and self._checkpoint_differs() and foreign != [MANIFEST]:
            foreign = sorted(set(foreign) | {"model.npz"})     # it is not run.json's either
        if foreign:
            raise RunFolderError(describe_foreign(self.path, foreign, ids))

    def check_checkpoint_belongs(self, meta: dict) -> None:
        """RunFolderError when model.npz (its configuration ``meta``) is not the run's: run.json's
        layout does not fit its network, or its fingerprint is not the one run.json recorded."""
        self.check_files_belong()
        config = meta.get("model_config") if isinstance(meta.get("model_config"), dict) else {}
        sizes = {"x": (self.layout.x_dim, config.get("x_dim")), "z": (self.layout.z_dim, config.get("z_dim"))}
        if any(b is not None and a != b for a, b in sizes.values()):
            shown = ", ".join(f"{k} {a} / {b}" for k, (a, b) in sizes.items())
            raise RunFolderError(f"run folder {self.path}: run.json's layout does not fit model.npz's network "
                                 f"(feature sizes run.json / model.npz: {shown}): one of them is another run's; "
                                 "a run's files are made together by minifilm train")
        if self.checkpoint_id is None or checkpoint_fingerprint(meta) == self.checkpoint_id:
            return
        vouching = [f for f, i in self.file_ids().items() if f not in (MANIFEST, "model.npz") and i is not None]
        if vouching:
            raise RunFolderError(f"run folder {self.path}: model.npz is not the checkpoint this run was trained "
                                 f"with (another run's, or changed since): run.json and "
                                 f"{' and '.join(vouching)} are of run {self.run_id}, whose checkpoint has the "
                                 f"fingerprint {self.checkpoint_id}, and model.npz's is {checkpoint_fingerprint(meta)}; "
                                 "put back this run's own model.npz")
        raise RunFolderError(f"run folder {self.path}: run.json and model.npz are of different runs (run.json "
                             f"records the checkpoint {self.checkpoint_id}, model.npz is {checkpoint_fingerprint(meta)}); "
                             "a run's files are made together by minifilm train")

    def template(self) -> Motion:
        """The source skeleton (one frame), in metres."""
        return read_bvh(note_input(self._file("skeleton.bvh")), scale=self.bvh_scale)

    def network(self) -> RuntimeNetwork:
        model, stats = self.model_and_stats()
        return RuntimeNetwork.from_model(model, stats)

    def adapters(self, network: RuntimeNetwork, names: Sequence[str]) -> dict:
        """Style -> StyleAdapter of the styles ``names`` taught with one ({} when none), checked
        against ``network`` (this run's)."""
        H = network.hidden.hidden
        return read_adapters(self.path, names, [network.x_dim, H, H, network.z_dim], network.n_experts,
                             RunFolderError)

    def adapted(self):
        """(network, style library) with the adapters of the run's styles applied while their style
        is on (minifilm/runtime/adapted.py); the plain ones when the run has none."""
        network, library = self.network(), self.styles()
        return with_adapters(network, library, self.adapters(network, library.names))

    def controller(self, network: Optional[RuntimeNetwork] = None, fit: bool = True, **options) -> Controller:
        """A Controller for this run: its layout and frame rate, the run's position bias, and (with
        ``fit``) every frame put on the source skeleton. ``options`` go to the Controller."""
        options.setdefault("position_bias", self.position_bias)
        if fit:
            options.setdefault("skeleton", Controller.skeleton_for(self.layout, self.template()))
        return Controller(network or self.network(), self.layout, fps=self.fps, **options)

    def start_states(self, names: Sequence[str]):
        """(x (B, x_dim), p (B, 8)) start frames for the styles ``names``, or (None, None) when any
        style has none (then rollouts start from the data's mean pose)."""
        starts = self.starts()
        if not names or any(n not in starts for n in names):
            return None, None
        return np.stack([starts[n][0] for n in names]), np.stack([starts[n][1] for n in names])
