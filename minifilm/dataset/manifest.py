"""Which BVH files make up a dataset, and their style and gait labels.

Two sources (used by :func:`minifilm.dataset.build.build_dataset`):

* a folder named like 100STYLE, ``<Style>_<Gait>.bvh`` with gait codes BR BW FR FW ID SR SW TR,
  TR1, TR2, ... (docs/original-code.md §11): :func:`scan_100style`;
* a CSV manifest for any other dataset, one row per file with the columns
  ``file, style, gait`` and optionally ``start, end`` (a frame range ``[start, end)``, 0-based,
  in the file's own frames) and ``mirror`` (yes/no: add a mirrored copy): :func:`read_manifest`.
  Relative paths are relative to the manifest's folder. :func:`write_bandai_manifest` writes one
  for the Bandai Namco datasets (``dataset-{1,2}_{content}_{style}_{id}.bvh``).
"""
from __future__ import annotations

import contextlib
import csv
import io
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, List, Optional, Sequence, Union

from minifilm.files import atomic_write, check_name, check_regular, few, open_regular, read_json

#: 100STYLE gait codes: forwards / backwards / sideways walk and run, idle, transitions.
STYLE100_GAITS = ("BR", "BW", "FR", "FW", "ID", "SR", "SW")
#: what dataset.json says of a data set folder that ``minifilm dataset --from-released`` wrote
MADE_BY = "minifilm dataset --from-released"
_STYLE100_NAME = re.compile(r"^(?P<style>[A-Za-z0-9]+)_(?P<gait>BR|BW|FR|FW|ID|SR|SW|TR[0-9]*)\.bvh$")
_BANDAI_NAME = re.compile(r"^dataset-(?P<set>[0-9]+)_(?P<content>[a-z\-]+)_(?P<style>[a-z]+)_(?P<id>[0-9]+)\.bvh$")
#: the largest CSV read (100STYLE's Frame_Cuts.csv is 8 KB; a manifest of 100,000 files ~10 MB)
MAX_CSV_BYTES = 64 << 20


@dataclass(frozen=True)
class MotionFile:
    """One file of a dataset.

    path: the BVH file; style, gait: labels; start, end: optional frame range ``[start, end)``;
    mirror: None = decided by the dataset settings (symmetric styles), True / False = forced.
    """
    path: Path
    style: str
    gait: str
    start: Optional[int] = None
    end: Optional[int] = None
    mirror: Optional[bool] = None


def scan_100style(folder: Union[str, Path]) -> List[MotionFile]:
    """Every ``<Style>_<Gait>.bvh`` in ``folder`` or its sub-folders (sorted by name; the 100STYLE
    download keeps one sub-folder per style). Files whose names do not follow the pattern are
    ignored; a folder without a single matching file, or two files of the same name, is an error.

    The 100STYLE metadata is used when it sits in the folder (docs/original-code.md §11):
    ``Frame_Cuts.csv`` crops each file to its stylised part (``<GAIT>_START`` / ``_STOP`` are 1-based
    inclusive frame numbers, read as ``[START-1, STOP)``; ``TR`` uses the ``TR1`` columns; N/A or a
    missing row keeps the whole file), and ``Dataset_List.csv`` marks the styles whose
    ``Symmetric`` column is Yes for mirroring (the others are not mirrored).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"scan_100style: {folder} is not a folder")
    cuts = read_frame_cuts(folder / "Frame_Cuts.csv") if os.path.lexists(folder / "Frame_Cuts.csv") else {}
    symmetric = (read_symmetric_styles(folder / "Dataset_List.csv")
                 if os.path.lexists(folder / "Dataset_List.csv") else None)
    out, seen = [], {}
    for path in sorted(folder.rglob("*.bvh"), key=lambda p: (p.name, str(p))):
        m = _STYLE100_NAME.match(path.name)
        if m:
            if path.name in seen:
                raise ValueError(f"scan_100style: {path.name} is both {seen[path.name]} and {path}; "
                                 f"keep one copy of each <Style>_<Gait>.bvh under {folder}")
            seen[path.name] = path
            style, gait = m["style"], m["gait"]
            start, end = cuts.get((style, "TR1" if gait == "TR" else gait), (None, None))
            mirror = None if symmetric is None else style in symmetric
            out.append(MotionFile(path, style, gait, start, end, mirror))
    if not out:
        raise ValueError(f"{folder}: no file in it is named <Style>_<Gait>.bvh with a gait of "
                         f"{', '.join(STYLE100_GAITS)} or TR, TR1, TR2, ... (100STYLE's naming), nor "
                         "dataset-N_<content>_<style>_<id>.bvh (Bandai Namco's); for other names list the "
                         "files in a CSV manifest and pass that (docs/own-data.md)")
    return out


@contextlib.contextmanager
def _csv_reader(csv_path: Path, encoding: str = "utf-8-sig") -> Iterator[csv.DictReader]:
    """A DictReader over the regular file ``csv_path``; every way its text can be broken (not
    UTF-8, a field over the csv module's limit, a stray quote) is one ValueError naming the line."""
    reader = None
    try:
        with open_regular(csv_path, "CSV file", MAX_CSV_BYTES) as raw, \
                io.TextIOWrapper(raw, encoding=encoding, newline="") as fh:
            reader = csv.DictReader(fh)
            yield reader
    except UnicodeDecodeError as e:
        raise _not_utf8(csv_path, e) from None
    except csv.Error as e:
        line = f": line {reader.line_num}" if reader is not None else ""
        raise ValueError(f"{csv_path}{line}: not a readable CSV row ({e})") from None


def _dict_rows(csv_path: Path):
    with _csv_reader(csv_path) as reader:
        for row in reader:
            yield reader.line_num, {(k or "").strip(): (v or "").strip() for k, v in row.items()}


def _not_utf8(csv_path: Path, e: UnicodeDecodeError) -> ValueError:
    return ValueError(f"{csv_path}: not UTF-8 text (byte {e.start} is {e.object[e.start:e.start + 1]!r}); "
                      "save it as UTF-8")


def read_frame_cuts(csv_path: Union[str, Path]) -> dict:
    """100STYLE ``Frame_Cuts.csv`` -> {(style, gait): (start, end)}, 0-based, end exclusive."""
    csv_path = Path(csv_path)
    out = {}
    for line, row in _dict_rows(csv_path):
        style = row.get("STYLE_NAME", "")
        if not style:
            raise ValueError(f"{csv_path}: line {line}: no STYLE_NAME")
        for key in row:
            if key.endswith("_START"):
                gait = key[:-6]
                a, b = row[key], row.get(gait + "_STOP", "")
                if a.upper() in ("", "N/A", "NA") or b.upper() in ("", "N/A", "NA"):
                    continue
                where = f"{csv_path}: line {line}"
                start, stop = _parse_int(a, key, where), _parse_int(b, gait + "_STOP", where)
                if start < 1 or stop < start:
                    raise ValueError(f"{where}: {gait} cut [{start}, {stop}] is not 1 <= START <= STOP")
                out[(style, gait)] = (start - 1, stop)
    return out


def read_symmetric_styles(csv_path: Union[str, Path]) -> set:
    """100STYLE ``Dataset_List.csv`` -> the set of styles whose ``Symmetric`` column is Yes."""
    csv_path = Path(csv_path)
    out = set()
    for line, row in _dict_rows(csv_path):
        name = row.get("Style Name", "")
        sym = row.get("Symmetric (Yes/No)", row.get("Symmetric", ""))
        if not name or sym.lower() not in ("yes", "no"):
            raise ValueError(f"{csv_path}: line {line}: expected 'Style Name' and 'Symmetric' Yes/No, "
                             f"got {name!r}, {sym!r}")
        if sym.lower() == "yes":
            out.add(name)
    return out


def _parse_int(text: str, what: str, where: str) -> Optional[int]:
    text = (text or "").strip()
    if text == "":
        return None
    if not re.fullmatch(r"-?[0-9]{1,12}", text):     # int() would also take "1_0" and other scripts' digits
        raise ValueError(f"{where}: column {what!r} must be a whole frame number, got {text[:40]!r}")
    value = int(text)
    if value < 0:
        raise ValueError(f"{where}: column {what!r} must be >= 0, got {value}")
    return value


def _parse_bool(text: str, where: str) -> Optional[bool]:
    t = (text or "").strip().lower()
    if t == "":
        return None
    if t in ("yes", "y", "true", "1"):
        return True
    if t in ("no", "n", "false", "0"):
        return False
    raise ValueError(f"{where}: column 'mirror' must be yes or no, got {text!r}")


def read_manifest(csv_path: Union[str, Path]) -> List[MotionFile]:
    """Read a CSV manifest (header ``file,style,gait[,start,end][,mirror]``); errors name the line."""
    csv_path = Path(csv_path)
    seen = {}
    with _csv_reader(csv_path, "utf-8") as reader:
        header = [h.strip() for h in (reader.fieldnames or [])]
        missing = [c for c in ("file", "style", "gait") if c not in header]
        if missing:
            raise ValueError(f"{csv_path}: line 1: header {header} lacks the column(s) {missing}; "
                             f"expected file,style,gait[,start,end][,mirror]")
        out = []
        for row in reader:
            where = f"{csv_path}: line {reader.line_num}"
            row = {(k or "").strip(): (v or "").strip() for k, v in row.items()}
            if not row.get("file"):
                raise ValueError(f"{where}: empty 'file'")
            if not row.get("style") or not row.get("gait"):
                raise ValueError(f"{where}: 'style' and 'gait' must not be empty")
            check_name(row["style"], f"{where}: column 'style'")
            check_name(row["gait"], f"{where}: column 'gait'")
            path = Path(row["file"])
            if not path.is_absolute():
                path = csv_path.parent / path
            if not os.path.exists(path):
                raise FileNotFoundError(f"{where}: file {path} does not exist")
            check_regular(path, f"{where}: file")
            start = _parse_int(row.get("start", ""), "start", where)
            end = _parse_int(row.get("end", ""), "end", where)
            if start is not None and end is not None and end <= start:
                raise ValueError(f"{where}: end {end} must be after start {start}")
            mirror = _parse_bool(row.get("mirror", ""), where)
            key = (path.resolve(), start, end, mirror)   # the same frames twice would weigh double
            if key in seen:
                raise ValueError(f"{where}: {path} (the same frames) is listed already on line {seen[key]}")
            seen[key] = reader.line_num
            out.append(MotionFile(path, row["style"], row["gait"], start, end, mirror))
    if not out:
        raise ValueError(f"{csv_path}: the manifest lists no files")
    return out


def write_manifest(files: Sequence[MotionFile], csv_path: Union[str, Path]) -> Path:
    """Write ``files`` as a CSV manifest (paths relative to the manifest's folder where possible)."""
    csv_path = Path(csv_path)
    folder = csv_path.parent.resolve()
    text = io.StringIO(newline="")
    w = csv.writer(text)
    w.writerow(["file", "style", "gait", "start", "end", "mirror"])
    for f in files:
        try:
            name = Path(f.path).resolve().relative_to(folder)
        except ValueError:
            name = Path(f.path).resolve()
        mirror = "" if f.mirror is None else ("yes" if f.mirror else "no")
        w.writerow([name.as_posix(), f.style, f.gait,
                    "" if f.start is None else f.start, "" if f.end is None else f.end, mirror])
    return atomic_write(csv_path, lambda fh: fh.write(text.getvalue().encode("utf-8")))


def bandai_files(folder: Union[str, Path]) -> List[MotionFile]:
    """Files of a Bandai Namco motion dataset folder, ``dataset-N_{content}_{style}_{id}.bvh``.

    style = the style word (``active``, ``elderly``, ...); gait = the content word (``walk``,
    ``run``, ``walk-turn-left``, ...), kept verbatim.
    """
    folder = Path(folder)
    out = []
    for path in sorted(folder.glob("*.bvh")):
        m = _BANDAI_NAME.match(path.name)
        if m:
            out.append(MotionFile(path, m["style"], m["content"]))
    if not out:
        raise ValueError(f"bandai_files: no file in {folder} is named dataset-N_<content>_<style>_<id>.bvh")
    return out


def write_bandai_manifest(folder: Union[str, Path], csv_path: Union[str, Path]) -> Path:
    """Write a CSV manifest for a Bandai Namco dataset folder (see :func:`bandai_files`)."""
    return write_manifest(bandai_files(folder), csv_path)


def scan_folder(folder: Union[str, Path]) -> List[MotionFile]:
    """The files of a motion folder, named either way minifilm knows: a Bandai Namco folder
    (``dataset-N_{content}_{style}_{id}.bvh``) or 100STYLE naming (``<Style>_<Gait>.bvh``, in the
    folder or its sub-folders). For any other naming, write a CSV manifest (:func:`read_manifest`)."""
    folder = Path(folder)
    if os.path.exists(folder) and not folder.is_dir():
        raise ValueError(f"{folder}: is a file, not a folder of BVH files or a .csv manifest")
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder")
    made = made_manifest(folder)
    if made is not None:
        return read_manifest(made)
    bandai = [p.name for p in sorted(folder.glob("*.bvh")) if _BANDAI_NAME.match(p.name)]
    if not bandai:
        return scan_100style(folder)
    style100 = [p.name for p in sorted(folder.glob("*.bvh")) if _STYLE100_NAME.match(p.name)]
    if style100:         # read one way, the others would be left out without a word
        raise ValueError(f"{folder}: holds files named both ways minifilm reads a folder: {len(bandai)} as "
                         f"Bandai Namco's dataset-N_<content>_<style>_<id>.bvh ({few(bandai, 2)}) and "
                         f"{len(style100)} as <Style>_<Gait>.bvh ({few(style100, 2)}); name them one way, "
                         "or list them all in a CSV manifest and pass that (docs/own-data.md)")
    return bandai_files(folder)


def made_manifest(folder: Path) -> Optional[Path]:
    """The manifest of a data set folder made by ``minifilm dataset --from-released`` (its
    dataset.json says so), or None. Such a folder is read by its manifest, which holds every
    file's true style name: a style's file name is only its name made safe (``Old Man`` ->
    ``Old Man_FW.bvh``, ``A:B`` -> ``A_B_FW.bvh``), which the 100STYLE file pattern cannot give back."""
    marker, manifest = folder / "dataset.json", folder / "manifest.csv"
    if not (marker.is_file() and manifest.is_file()):
        return None
    try:
        info = read_json(marker, "data set description")
    except (ValueError, OSError):
        return None
    return manifest if isinstance(info, dict) and info.get("made_by") == MADE_BY else None
