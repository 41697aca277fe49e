"""How fast is the viewer? Its targets (GIF ≤ 30 s, HTML ≤ 5 MB and ready in ≤ 2 s), measured.

1. GIF: 6 s of 8 characters at 30 fps (8 Bandai clips when ../shared/data is there, else
   synthetic walkers), written with ``write_gif``: target <= 30 s on the 2-core machine.
2. HTML: the page for 8 characters x 10 s at 60 fps: size (target <= 5 MB) and the time until
   the player is ready in headless Chromium, opened from disk (target <= 2 s). The 60 fps data
   are Bandai clips interpolated to 60 fps and looped to 10 s (same skeleton, 21 drawn joints);
   a second row uses the CMU skeleton (more joints, fingers) as a heavier case.

Prints the minimum (and median) of several runs and the machine load (1-minute load average,
before and after), since other work may share the cores.

    python benchmarks/viewer.py [--repeat 3] [--loads 5]
"""
import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from minifilm.viewer import Track, track_from_bvh, write_gif, write_html

DATA = Path(os.environ.get("MINIFILM_SHARED_DATA", ROOT.parent / "shared" / "data"))
CHROMIUM = os.environ.get("MINIFILM_CHROMIUM", "/usr/bin/chromium")


def load() -> str:
    return "load %.2f %.2f %.2f" % os.getloadavg()


def gif_tracks():
    """8 tracks at 30 fps, at least 6 s long: Bandai clips, or synthetic ones without the data."""
    files = sorted((DATA / "bandai2").glob("dataset-2_*_001.bvh")) if DATA.is_dir() else []
    if len(files) >= 8:
        return [track_from_bvh(f, name=f.stem[10:-4]) for f in files[:8]], "Bandai clips"
    return [synthetic_track(f"walker {i}", 30.0, 6.0, phase=i) for i in range(8)], "synthetic walkers"


def synthetic_track(name, fps, seconds, phase=0.0) -> Track:
    """A 21-joint stick figure: a stand-in when the real data is not there."""
    t = np.arange(int(round(fps * seconds)))[:, None] / fps
    rest = np.array([[0, 1, 0], [0, 1.3, 0], [0, 1.6, 0], [0, 1.75, 0]] + [[0, 1.0, 0]] * 17, dtype=float)
    P = np.repeat(rest[None], len(t), axis=0)
    P[:, 4:, 0] = np.linspace(-0.3, 0.3, 17)
    P[:, 4:, 1] = np.linspace(0.1, 1.4, 17)[None] + 0.05 * np.sin(2 * np.pi * t + phase)
    P[:, :, 2] += 1.4 * t
    parents = [-1, 0, 1, 2] + [0] * 17
    return Track(name, P, parents, fps)


def at_60fps(track: Track, seconds: float) -> Track:
    """``track`` linearly interpolated to 60 fps and looped to ``seconds`` (positions only)."""
    n = int(round(60 * seconds))
    src = np.arange(n) / 60.0 * track.fps % (track.n_frames - 1)
    i = np.floor(src).astype(int)
    w = (src - i)[:, None, None]
    P = (1 - w) * track.positions[i] + w * track.positions[i + 1]
    return Track(track.name, P, track.parents, 60.0)


def html_tracks():
    rows = []
    base, source = gif_tracks()
    rows.append((f"8 x 10 s x 60 fps, {base[0].n_joints} joints ({source})", [at_60fps(t, 10.0) for t in base]))
    cmu = DATA / "bvh" / "cmu" / "08_01_trimmed.bvh"
    if cmu.is_file():
        c = track_from_bvh(cmu)
        rows.append((f"8 x 10 s x 60 fps, {c.n_joints} joints (CMU skeleton)", [at_60fps(c, 10.0)] * 8))
    return rows


def bench_gif(repeat: int, folder: Path) -> None:
    tracks, source = gif_tracks()
    times = []
    print(f"GIF: 8 characters ({source}), 6 s at 30 fps, 240 x 300 px panels   [{load()}]")
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = write_gif(tracks, folder / "bench.gif", seconds=6.0)
        times.append(time.perf_counter() - t0)
    size = (folder / "bench.gif").stat().st_size / 1e6
    print(f"  {r.n_frames} frames, {r.size[0]} x {r.size[1]} px, {size:.1f} MB: "
          f"min {min(times):.1f} s, median {statistics.median(times):.1f} s over {repeat} runs "
          f"(target <= 30 s)   [{load()}]")


def bench_html(loads: int, folder: Path) -> None:
    print(f"HTML: 8 characters x 10 s x 60 fps   [{load()}]")
    pages = []
    for label, tracks in html_tracks():
        path = folder / f"bench{len(pages)}.html"
        t0 = time.perf_counter()
        write_html(tracks, path)
        took = time.perf_counter() - t0
        print(f"  {label}: {path.stat().st_size / 1e6:.2f} MB (target <= 5 MB), written in {took:.2f} s")
        pages.append((label, path))
    try:
        from playwright.sync_api import sync_playwright  # optional: only for the load time
    except ImportError:
        print("  (playwright is not installed: no load time)")
        return
    if not Path(CHROMIUM).is_file():
        print(f"  (no Chromium at {CHROMIUM}: no load time)")
        return
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM,
                                    args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
        for label, path in pages:
            wall, inpage = [], []
            for _ in range(loads):
                page = browser.new_page(viewport={"width": 1280, "height": 720})
                t0 = time.perf_counter()
                page.goto(path.resolve().as_uri())
                page.wait_for_function("window.minifilmPlayer && window.minifilmPlayer.ready", polling=10)
                wall.append(time.perf_counter() - t0)
                inpage.append(page.evaluate("minifilmPlayer.readyMs") / 1000)
                page.close()
            print(f"  {label}: ready after min {min(inpage):.2f} s (page clock), {min(wall):.2f} s (wall, "
                  f"from goto), median {statistics.median(wall):.2f} s over {loads} loads (target <= 2 s)")
        browser.close()
    print(f"  [{load()}]")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="GIF runs")
    parser.add_argument("--loads", type=int, default=5, help="page loads per HTML file")
    args = parser.parse_args()
    print(f"{os.cpu_count()} cores; data: {DATA if DATA.is_dir() else 'absent'}")
    with tempfile.TemporaryDirectory() as folder:
        bench_gif(args.repeat, Path(folder))
        bench_html(args.loads, Path(folder))


if __name__ == "__main__":
    main()
