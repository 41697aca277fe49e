"""Checkpoints: one ``.npz`` file holding arrays and a JSON description, written atomically.

Layout of the archive (every entry a plain numeric or unicode array, so it loads with
``allow_pickle=False``; nothing in a checkpoint can run code):

    meta.json            0-d unicode array: JSON text {"format", "model_config", "train_config",
                         "epoch", "step", "history", "rng_state", "style_names", ...}
    gating.<name>        Ω parameters      (Parameters.state_dict of each network)
    motion.<name>        Φ parameters
    film.<name>          Ψ parameters (absent for a model without Ψ)
    adam.<key>           optimiser moments and step counts (Adam.state_dict)
    stats.<name>         normalisation statistics (NormStats.to_arrays)

Writing goes to a temporary file in the same folder, is flushed to disk, then renamed over the
target with os.replace, so a crash (or a NaN stop) never leaves half a checkpoint and the last
good one stays intact.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from minifilm.errors import InputError
from minifilm.files import MAX_JSON_BYTES, MAX_NPZ_BYTES, Member, atomic_savez, parse_json, read_npz, read_npz_member
from minifilm.model.config import ModelConfig
from minifilm.model.film_generator import film_shapes
from minifilm.model.gating import gating_shapes
from minifilm.model.motion_net import motion_shapes
from minifilm.model.style_model import StyleModel

FORMAT = "minifilm-checkpoint-1"
NETWORKS = ("gating", "motion", "film")


class CheckpointError(InputError):
    """A checkpoint file is missing, unreadable, or does not hold what it should."""


def save_checkpoint(path, meta: dict, arrays: dict) -> None:
    """Atomically write `arrays` (name -> ndarray) and `meta` (JSON-serialisable) to `path`."""
    payload = {"meta.json": np.array(json.dumps({"format": FORMAT, **meta}))}
    for name, arr in arrays.items():
        if name == "meta.json":
            raise ValueError("save_checkpoint: 'meta.json' is a reserved array name")
        payload[name] = np.asarray(arr)
    atomic_savez(path, payload)


def load_checkpoint(path) -> tuple[dict, dict]:
    """Read a checkpoint -> (meta dict, arrays dict). Raises CheckpointError naming the file.

    Its small meta.json is read first; the arrays' headers are then checked against the model its
    configuration describes (every parameter's shape, the statistics' sizes, a memory budget of the
    parameters and the optimiser's two moments) before any of their data is read."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"checkpoint {path}: no such file")
    text = read_npz_member(path, "meta.json", "checkpoint", CheckpointError, Member("U", ()), MAX_JSON_BYTES)
    if text is None:
        raise CheckpointError(f"checkpoint {path}: missing 'meta.json' entry")
    meta = parse_json(str(text), f"checkpoint {path}: 'meta.json'", CheckpointError)
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CheckpointError(f"checkpoint {path}: format is {meta.get('format') if isinstance(meta, dict) else meta!r}, "
                              f"expected {FORMAT!r}")
    members, budget = _expected_members(meta, path)
    arrays = read_npz(path, "checkpoint", CheckpointError, budget, members)
    arrays.pop("meta.json")
    _check_config_fits(meta, arrays, path)
    return meta, arrays


def _expected_members(meta: dict, path: Path):
    """(name -> Member, bytes) the checkpoint of ``meta`` holds: for the paper's style model every
    parameter's exact shape and the statistics' sizes, and as many bytes as its parameters and the
    optimiser's two moments take in float64 (at most the general budget of an archive); for a comparison variant (minifilm/baselines, whose
    networks are shaped otherwise) float arrays within the general budget of an archive."""
    members = {"meta.json": Member("U", ()), "adam.steps": Member("iu", (None,), optional=True),
               "adam.*": Member("f", (None,)), "stats.*": Member("f", (None,))}
    members.update({f"{net}.*": Member("f", None) for net in NETWORKS})
    variant = meta.get("variant") or {}
    if "model_config" not in meta or not isinstance(variant, dict) or variant.get("name") not in (None, "LPN FiLM"):
        return members, MAX_NPZ_BYTES
    try:
        c = ModelConfig.from_dict(meta["model_config"])
    except (ValueError, TypeError, KeyError, AttributeError) as e:
        raise CheckpointError(f"checkpoint {path}: model configuration: {e}") from None
    shapes = {"gating": gating_shapes(c), "motion": motion_shapes(c)}
    if meta.get("has_film_generator", True):
        shapes["film"] = film_shapes(c)
    members = {k: m for k, m in members.items() if k.split(".")[0] not in NETWORKS}
    for net, sizes in shapes.items():
        members.update({f"{net}.{name}": Member("f", shape, optional=True) for name, shape in sizes.items()})
    for part, size in (("x", c.x_dim), ("z", c.z_dim), ("p", c.phase_dim)):
        members.update({f"stats.{part}_{k}": Member("f", (size,), optional=True) for k in ("mean", "std")})
    budget = 8 * (3 * c.n_parameters + 2 * (c.x_dim + c.z_dim + c.phase_dim)) + 2 * MAX_JSON_BYTES
    return members, min(budget, MAX_NPZ_BYTES)


def _check_config_fits(meta: dict, arrays: dict, path: Path) -> None:
    """The stored configuration must be valid and describe about as many parameters as the file
    holds: a forged ``hidden`` must fail here, before a model of that size is allocated."""
    if "model_config" not in meta:
        return
    try:
        config = ModelConfig.from_dict(meta["model_config"])
    except (ValueError, TypeError, KeyError, AttributeError) as e:
        raise CheckpointError(f"checkpoint {path}: model configuration: {e}") from None
    stored = sum(a.size for k, a in arrays.items() if k.split(".")[0] in NETWORKS)
    if config.n_parameters > 2 * stored + 1_000_000:
        raise CheckpointError(f"checkpoint {path}: its configuration describes {config.n_parameters:,} parameters "
                              f"but the file holds {stored:,}")


def subset(arrays: dict, prefix: str) -> dict:
    """Entries 'prefix.name' -> {'name': array}."""
    n = len(prefix) + 1
    return {k[n:]: v for k, v in arrays.items() if k.startswith(prefix + ".")}


def model_arrays(model) -> dict:
    """name -> array for every parameter of the model, prefixed by network."""
    out = {}
    for net in NETWORKS:
        sub = getattr(model, net)
        if sub is not None:
            out.update({f"{net}.{k}": v for k, v in sub.params.state_dict().items()})
    return out


def load_model_arrays(model, arrays: dict, path="checkpoint", networks=NETWORKS) -> None:
    """Copy the checkpoint's parameters into `model` (clear error on missing/misshaped arrays)."""
    for net in networks:
        sub = getattr(model, net)
        if sub is None:
            continue
        state = subset(arrays, net)
        for name, value in state.items():
            value = np.asarray(value)
            if value.dtype.kind != "f" or not np.all(np.isfinite(value)):
                raise CheckpointError(f"{path}: parameter '{net}.{name}' holds non-finite or non-float values "
                                      f"({value.dtype}); the checkpoint is corrupt")
        try:
            sub.params.load_state_dict(state, strict=True)
        except (KeyError, ValueError) as e:
            raise CheckpointError(f"{path}: parameters of '{net}' do not fit the model: {e}") from e


def build_style_model(meta: dict) -> StyleModel:
    """The paper's StyleModel for a checkpoint's metadata (weights not loaded yet).

    A checkpoint of a comparison variant other than the LPN + FiLM (Sec. 5) is refused with a
    CheckpointError naming it: those are rebuilt by minifilm.baselines.variants.model_from_checkpoint.
    """
    variant = meta.get("variant") or {}
    if variant.get("name") not in (None, "LPN FiLM"):
        raise CheckpointError(f"checkpoint holds the comparison model {variant['name']!r}, not the paper's "
                              "style model; load it with build_model=minifilm.baselines.variants.model_from_checkpoint")
    config = ModelConfig.from_dict(meta["model_config"])
    return StyleModel(config, np.random.default_rng(0), with_film_generator=meta.get("has_film_generator", True))
