"""Fuzzing the command line: absurd, malformed and careless arguments to every command.

Each case runs ``minifilm ...`` in this process and must exit with code 2 and one line
``error: ...`` on stderr naming the argument or file, before any output is written, and leave the
run folder it was given exactly as it was. A few well-formed cases must work (exit 0).
"""
import hashlib
import shutil
from pathlib import Path

import pytest
from in_process import minifilm_here


R = "{run}"          # placeholders, filled in per case
T = "{tmp}"
NUMBERS = {
    "generate --seconds": ["-1", "0", "nan", "inf", "abc", "", "1e9", "-0", "1e309"],
    "generate --speed": ["-1", "nan", "inf", "abc", "11", "1e9"],
    "generate --blend": ["-0.1", "1.5", "nan", "inf", "abc", "1000"],
    "generate --switch-at": ["-1", "nan", "inf", "abc", "5"],
    "generate --png-every": ["0", "-1", "1.5", "abc", "nan"],
    "generate --png-from": ["-1", "nan", "abc"],
    "train --epochs": ["0", "-1", "abc", "1e9", "1.5"],
    "train --seconds": ["0", "-1", "nan"],
    "train --clips-per-batch": ["0", "-3", "abc"],
    "train --fps": ["0", "-30", "nan", "5000"],
    "train --clip-seconds": ["0", "-1", "nan", "100"],
    "finetune --steps": ["0", "-1", "abc", "1e9"],
    "finetune --lr": ["0", "-1", "nan", "2"],
    "finetune --rollout-rounds": ["-1", "1.5", "101", "x"],
    "table2 --styles": ["-3", "0", "abc"],
    "table2 --runs": ["0", "-1"],
    "compare --epochs": ["0", "-5"],
    "gradcheck --seeds": ["0", "-1", "x"],
    "dataset --clip-seconds": ["0", "-2", "nan"],
    "phases --start": ["-1", "nan"],
    "view --every": ["0", "-2"],
}
BASE = {
    "generate": ["generate", "--run", R, "--seconds", "1", "--out", f"{T}/out.bvh"],
    "train": ["train", "--quick", "--out", f"{T}/train"],
    "finetune": ["finetune", "--run", R, "--name", "New", f"{R}/data/Neutral_FW.bvh"],
    "table2": ["table2", "--no-timing"],
    "compare": ["compare", "--tiny", "--out", f"{T}/cmp", "--work", f"{T}/work"],
    "gradcheck": ["gradcheck"],
    "dataset": ["dataset", f"{R}/data", "--cache", f"{T}/cache"],
    "phases": ["phases", f"{R}/data/Neutral_FW.bvh", "--out", f"{T}/p.png"],
    "view": ["view", f"{R}/data/Neutral_FW.bvh", "--gif", f"{T}/v.gif"],
    "retarget": ["retarget", f"{R}/data/Neutral_FW.bvh", "--to", "bandai", "--out", f"{T}/rt"],
}


def _numeric_cases():
    out = []
    for key, values in NUMBERS.items():
        command, flag = key.split()
        for v in values:
            args = list(BASE[command])
            if command == "generate" and flag in ("--blend",):
                args += ["--style2", "LeftHop"]
            if command == "generate" and flag == "--switch-at":
                args += ["--switch-to", "LeftHop"]
            if command == "generate" and flag.startswith("--png"):
                args += ["--png", f"{T}/g.png"]
            out.append((f"{key} {v!r}", args + [flag, v]))
    return out


OTHER = [
    ("no command", []),
    ("unknown command", ["fly"]),
    ("generate: unknown style", BASE["generate"] + ["--style", "Nope"]),
    ("generate: empty style", BASE["generate"] + ["--style", ""]),
    ("generate: unknown second style", BASE["generate"] + ["--style2", "Nope", "--blend", "0.5"]),
    ("generate: weights not summing to 1", BASE["generate"] + ["--style2", "LeftHop", "--style3", "Neutral",
                                                               "--weights", "0.5", "0.5", "0.5"]),
    ("generate: negative weight", BASE["generate"] + ["--style2", "LeftHop", "--style3", "Neutral",
                                                      "--weights", "-1", "1", "1"]),
    ("generate: weights without style3", BASE["generate"] + ["--weights", "0.2", "0.3", "0.5"]),
    ("generate: unknown script", BASE["generate"] + ["--script", "circle"]),
    ("generate: unknown fit", BASE["generate"] + ["--fit", "bad"]),
    ("generate: out is a folder", ["generate", "--run", R, "--seconds", "1", "--out", T]),
    ("generate: out under a file", ["generate", "--run", R, "--seconds", "1", "--out", f"{R}/run.json/x.bvh"]),
    ("generate: gif is a folder", BASE["generate"] + ["--gif", T]),
    ("generate: run missing", ["generate", "--run", f"{T}/nope", "--out", f"{T}/o.bvh"]),
    ("generate: run is a file", ["generate", "--run", f"{R}/run.json", "--out", f"{T}/o.bvh"]),
    ("generate: run without run.json", ["generate", "--run", T, "--out", f"{T}/o.bvh"]),
    ("generate: params missing", ["generate", "--params", f"{T}/nope", "--out", f"{T}/o.bvh"]),
    ("generate: params not released", ["generate", "--params", R, "--out", f"{T}/o.bvh"]),
    ("generate: both run and params", ["generate", "--run", R, "--params", R, "--out", f"{T}/o.bvh"]),
    ("generate: skeleton missing", BASE["generate"] + ["--skeleton-bvh", f"{T}/nope.bvh"]),
    ("generate: skeleton not BVH", BASE["generate"] + ["--skeleton-bvh", f"{R}/run.json"]),
    ("generate: skeleton of another body", BASE["generate"] + ["--skeleton-bvh", "{shared}/bandai2/dataset-2_walk_normal_001.bvh"]),
    ("train: data missing", ["train", "--data", f"{T}/nope", "--out", f"{T}/t"]),
    ("train: data an empty folder", ["train", "--data", T, "--out", f"{T}/t"]),
    ("train: data a BVH file", ["train", "--data", f"{R}/data/Neutral_FW.bvh", "--out", f"{T}/t"]),
    ("train: unknown style", BASE["train"] + ["--styles", "Nope"]),
    ("train: empty styles", BASE["train"] + ["--styles", ""]),
    ("train: unknown gait", BASE["train"] + ["--gaits", "XX"]),
    ("train: unknown split", BASE["train"] + ["--split", "halves"]),
    ("train: out is a file", ["train", "--out", f"{R}/run.json"]),
    ("finetune: clip missing", ["finetune", "--run", R, "--name", "New", f"{T}/nope.bvh"]),
    ("finetune: clip not BVH", ["finetune", "--run", R, "--name", "New", f"{R}/run.json"]),
    # a clip of another humanoid rig is retargeted (docs/retargeting.md); one that is no humanoid is refused
    ("finetune: clip of a rig that is no humanoid", ["finetune", "--run", R, "--name", "New", f"{T}/chain.bvh"]),
    ("finetune: clip too short", ["finetune", "--run", R, "--name", "New", f"{T}/short.bvh"]),
    ("finetune: name exists", ["finetune", "--run", R, "--name", "Neutral", f"{R}/data/Neutral_FW.bvh"]),
    ("finetune: empty name", ["finetune", "--run", R, "--name", "", f"{R}/data/Neutral_FW.bvh"]),
    ("finetune: name with a slash", ["finetune", "--run", R, "--name", "a/b", f"{R}/data/Neutral_FW.bvh"]),
    ("finetune: name too long", ["finetune", "--run", R, "--name", "x" * 100, f"{R}/data/Neutral_FW.bvh"]),
    ("finetune: not a run", ["finetune", "--run", T, "--name", "New", f"{R}/data/Neutral_FW.bvh"]),
    ("finetune: no clip", ["finetune", "--run", R, "--name", "New"]),
    ("finetune: workers without motion rounds", ["finetune", "--run", R, "--name", "New", "--workers", "2",
                                                 f"{R}/data/Neutral_FW.bvh"]),
    ("phases: file missing", ["phases", f"{T}/nope.bvh"]),
    ("phases: out is a folder", ["phases", f"{R}/data/Neutral_FW.bvh", "--out", T]),
    ("phases: not BVH", ["phases", f"{R}/run.json", "--out", f"{T}/p.png"]),
    ("phases: unknown skeleton", BASE["phases"] + ["--skeleton", "robot"]),
    ("phases: stop before start", BASE["phases"] + ["--start", "3", "--stop", "1"]),
    # every source is read before anything is printed or written (a good file comes first)
    ("retarget: source missing", BASE["retarget"][:2] + [f"{T}/nope.bvh"] + BASE["retarget"][2:]),
    ("retarget: source not BVH", BASE["retarget"][:2] + [f"{R}/run.json"] + BASE["retarget"][2:]),
    ("retarget: source no humanoid", BASE["retarget"][:2] + [f"{T}/chain.bvh"] + BASE["retarget"][2:]),
    ("retarget: map missing", BASE["retarget"] + ["--map", f"{T}/nope.json"]),
    ("retarget: unknown target", ["retarget", f"{R}/data/Neutral_FW.bvh", "--to", "robot", "--out", f"{T}/rt"]),
    ("retarget: same name twice", BASE["retarget"][:2] + [f"{R}/data/Neutral_FW.bvh"] + BASE["retarget"][2:]),
    ("view: file missing", ["view", f"{T}/nope.bvh", "--gif", f"{T}/v.gif"]),
    ("view: gif is a folder", ["view", f"{R}/data/Neutral_FW.bvh", "--gif", T]),
    ("view: not BVH", ["view", f"{R}/run.json", "--gif", f"{T}/v.gif"]),
    ("view: size 0", BASE["view"] + ["--size", "0", "100"]),
    ("dataset: folder missing", ["dataset", f"{T}/nope"]),
    ("dataset: cache is a file", ["dataset", f"{R}/data", "--cache", f"{R}/run.json"]),
    ("compare: data missing", ["compare", "--data", f"{T}/nope", "--tiny"]),
    ("compare: unknown variant", BASE["compare"] + ["--variants", "Bogus"]),
    ("compare: seeds not numbers", BASE["compare"] + ["--extra-seeds", "x"]),
    ("compare: one style to interpolate", BASE["compare"] + ["--interpolate", "Drunk"]),
    ("compare: work is a file", ["compare", "--tiny", "--work", f"{R}/run.json"]),
    ("compare: unknown held-out style", BASE["compare"] + ["--data", f"{R}/data", "--holdout", "Nope"]),
    ("compare: unknown style to interpolate", BASE["compare"] + ["--data", f"{R}/data", "--holdout", "Neutral",
                                                                 "--interpolate", "Nope,LeftHop"]),
    ("generate: too short for one frame", BASE["generate"] + ["--seconds", "1e-6"]),
    ("phases: skeleton of another rig", BASE["phases"] + ["--skeleton", "cmu"]),
    ("view: name too long", BASE["view"] + ["--gif", f"{T}/" + "a" * 300 + ".gif"]),
    ("generate: name too long", BASE["generate"] + ["--out", f"{T}/new/" + "a" * 240 + ".bvh"]),
    ("gradcheck: no row matches", ["gradcheck", "--only", "no such backward pass"]),
    ("train: --fps without --data", ["train", "--quick", "--fps", "30", "--out", f"{T}/run"]),
    ("train: --mirror without --data", ["train", "--quick", "--mirror", "--out", f"{T}/run"]),
    ("train: synthetic styles with --data", ["train", "--quick", "--data", f"{R}/data", "--styles", "Limp",
                                             "--out", f"{T}/run"]),
    ("dataset: mirror an unknown style", ["dataset", f"{R}/data", "--mirror", "Bogus", "--no-cache"]),
]
CASES = _numeric_cases() + OTHER


def snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def run_copy(tiny_run, tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli") / "run"
    shutil.copytree(tiny_run, folder, ignore=shutil.ignore_patterns("cache", "generated", "*.png"))
    return folder, snapshot(folder)


def fill(args, run, tmp, shared):
    return [a.replace(R, str(run)).replace(T, str(tmp)).replace("{shared}", str(shared)) for a in args]


#: a single chain of three bones, 200 frames: a rig with no legs, arms or head to find
CHAIN_BVH = ("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
             " JOINT B\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  JOINT C\n  {\n"
             "   OFFSET 0 10 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n   End Site\n   {\n    OFFSET 0 10 0\n"
             "   }\n  }\n }\n}\nMOTION\nFrames: 200\nFrame Time: 0.0166667\n"
             + "".join(f"{0.01 * i} 90 0 0 {i % 30} 0 0 0 0 0 0 0\n" for i in range(200)))


@pytest.mark.parametrize("name,args", CASES, ids=[c[0] for c in CASES])
def test_bad_arguments_are_one_line_and_change_nothing(run_copy, tmp_path, shared_data, capsys, name, args):
    run, before = run_copy
    lines = (run / "data" / "Neutral_FW.bvh").read_text().splitlines()
    frames_at = next(i for i, line in enumerate(lines) if line.startswith("Frames:"))
    (tmp_path / "short.bvh").write_text("\n".join(lines[:frames_at] + ["Frames: 5"] + lines[frames_at + 1:frames_at + 7]) + "\n")
    (tmp_path / "chain.bvh").write_text(CHAIN_BVH)
    existing = set(tmp_path.rglob("*"))
    code, out = minifilm_here(fill(args, run, tmp_path, shared_data), capsys)
    errors = [line for line in out.err.splitlines() if line.startswith("error:") or "minifilm: unknown" in line]
    assert code == 2, (code, out.err[-500:])
    assert "Traceback" not in out.err
    assert len(errors) == 1 or not args, out.err[-500:]
    assert set(tmp_path.rglob("*")) == existing, "wrote something"
    assert snapshot(run) == before, "changed the run folder"
    if args and args[0] == "retarget":
        assert out.out == "", f"printed before every input was checked: {out.out!r}"


def test_well_formed_commands_work(run_copy, tmp_path, capsys):
    """The same commands with good arguments: generate, a fine-tune on a copy, phases, view."""
    run, _ = run_copy
    work = tmp_path / "run"
    shutil.copytree(run, work)
    for argv in (["generate", "--run", str(work), "--seconds", "1", "--out", str(tmp_path / "a.bvh")],
                 ["generate", "--run", str(work), "--seconds", "1", "--style2", "LeftHop", "--blend", "0.5",
                  "--out", str(tmp_path / "b.bvh")],
                 ["finetune", "--run", str(work), "--name", "New", "--steps", "5", str(work / "data" / "Neutral_FW.bvh")],
                 ["generate", "--run", str(work), "--seconds", "1", "--style", "New", "--out", str(tmp_path / "c.bvh")]):
        code, out = minifilm_here(argv, capsys)
        assert code == 0, out.err[-800:]
    for name in ("a.bvh", "b.bvh", "c.bvh"):
        assert (tmp_path / name).stat().st_size > 1000


def test_there_are_enough_cases():
    assert len(CASES) >= 120, len(CASES)
