"""Draw the style model, Ω, Φ and Ψ, with the tensor shape on every edge (the paper's Figure 3).

    python scripts/figure_model.py                     # writes docs/img/model_shapes.png
    python scripts/figure_model.py --out model.png

Two panels: the main job's model (``ModelConfig.small`` at 100STYLE's feature sizes and the main
job's 2 s clips at 60 fps) and the paper's (``ModelConfig.paper``). Every shape is computed from the
configuration and the networks' parameter shapes (``gating_shapes``, ``motion_shapes``,
``film_shapes``), never typed in, so the figure follows the code when a size changes. B is the
batch; a training minibatch holds one style, and at run time Ψ is replaced by a stored FiLM vector.
"""
from __future__ import annotations

import argparse
import inspect
import io
from pathlib import Path

import numpy as np

from minifilm.features.layout import FeatureLayout
from minifilm.model.config import ModelConfig
from minifilm.model.film_generator import film_shapes
from minifilm.model.gating import gating_shapes
from minifilm.model.motion_net import motion_shapes
from minifilm.model.style_model import parameter_counts
from minifilm.motion.skeletons import STYLE100
from minifilm.pipeline.train_small import Settings
from minifilm.synthetic.generator import default_dataset
from minifilm.viewer.deps import pyplot

ROOT = Path(__file__).resolve().parents[1]
COLOURS = {"Ψ": "#cfe8cf", "Φ": "#f8d9bf", "Ω": "#d5e3f4", "in": "#ffffff"}
EDGE = "#8a1c1c"          # the colour of the shapes on the edges


def small_config() -> ModelConfig:
    """The main job's model: 100STYLE's feature sizes, clips of Settings.clip_seconds at the
    synthetic data's frame rate."""
    layout = FeatureLayout.for_skeleton(STYLE100)
    fps = inspect.signature(default_dataset).parameters["fps"].default
    return ModelConfig.small(layout.x_dim, layout.z_dim, int(round(Settings().clip_seconds * fps)), layout.clip_dim)


def shape(*dims) -> str:
    return "(" + ", ".join(str(d) for d in dims) + ")"


def rows(c: ModelConfig):
    """The three networks as chains of (box text, shape of the edge leaving it), from the config."""
    g, m, f = gating_shapes(c), motion_shapes(c), film_shapes(c)
    T, T2, T4, Fn, H = c.clip_frames, c.clip_frames // 2, c.pooled_frames, c.conv_filters, c.hidden
    psi = [("style clip y", shape("B", T, c.clip_channels)),
           (f"conv1d, 'same'\nW {shape(*f['conv0_W'])}\n→ ReLU", shape("B", T, Fn)),
           ("max-pool 2", shape("B", T2, Fn)),
           (f"conv1d, 'same'\nW {shape(*f['conv1_W'])}\n→ ReLU", shape("B", T2, Fn)),
           ("max-pool 2", shape("B", T4, Fn)),
           ("flatten\n(time-major)", shape("B", c.flat_dim)),
           (f"dense\nW {shape(*f['dense0_W'])}\n→ ReLU", shape("B", c.film_dense)),
           (f"dropout →\ndense\nW {shape(*f['dense1_W'])}", shape("B", c.film_dim)),
           ("γ1 β1 γ2 β2\n(Eq. 2)", None)]
    phi = [("input frame x", shape("B", c.x_dim))]
    for l in (0, 1):
        phi += [(f"dropout →\n{c.n_experts} experts\nW{l} {shape(*m[f'W{l}'])}", shape("B", H)),
                ("layer norm\n(F − μ) / σ", shape("B", H)), (f"FiLM\nγ{l + 1} ∘ · + β{l + 1}", shape("B", H)),
                ("ELU", shape("B", H))]
    phi += [(f"dropout →\n{c.n_experts} experts\nW2 {shape(*m['W2'])}", shape("B", c.z_dim)), ("output ẑ", None)]
    omega = [("local phases p\n(Eq. 1)", shape("B", c.phase_dim)),
             (f"dropout →\ndense {shape(*g['W0'])}\n→ ELU", shape("B", c.gating_hidden)),
             (f"dropout →\ndense {shape(*g['W1'])}\n→ ELU", shape("B", c.gating_hidden)),
             (f"dropout →\ndense {shape(*g['W2'])}\n→ softmax", shape("B", c.n_experts)),
             ("expert weights α", None)]
    return psi, phi, omega


def draw_chain(ax, items, y, x0, width, colour, box_w, height=4.0):
    """Boxes left to right from x0, spread over width, each edge labelled with its shape above the
    arrow; returns each box's (x centre, y)."""
    plt, step, centres = pyplot(), width / len(items), []
    for i, (text, edge) in enumerate(items):
        cx = x0 + step * (i + 0.5)
        end = i == 0 or edge is None                     # inputs and outputs: dashed, white
        ax.add_patch(plt.Rectangle((cx - box_w / 2, y - height / 2), box_w, height, linewidth=0.9, edgecolor="0.25",
                                   facecolor=COLOURS["in"] if end else colour, linestyle="--" if end else "-"))
        ax.text(cx, y, text, ha="center", va="center", fontsize=7.5)
        if edge is not None:
            nx = cx + step
            ax.annotate("", xy=(nx - box_w / 2, y), xytext=(cx + box_w / 2, y),
                        arrowprops=dict(arrowstyle="-|>", color="0.2", lw=0.9))
            ax.text((cx + nx) / 2, y + height / 2 + 0.35, edge, ha="center", va="bottom", fontsize=7.5, color=EDGE)
        centres.append((cx, y))
    return centres


def bus(ax, source, targets, y_bus, labels, colour, height=4.0):
    """One tensor handed to several boxes: a line from source to y_bus, along it, into each target."""
    xs = [x for x, _ in targets] + [source[0]]
    ax.plot([source[0], source[0]], [source[1] + np.sign(y_bus - source[1]) * height / 2, y_bus], color=colour, lw=0.9)
    ax.plot([min(xs), max(xs)], [y_bus, y_bus], color=colour, lw=0.9)
    for (x, y), label in zip(targets, labels):
        ax.annotate("", xy=(x, y + np.sign(y_bus - y) * height / 2), xytext=(x, y_bus),
                    arrowprops=dict(arrowstyle="-|>", color=colour, lw=0.9))
        ax.text(x + 0.4, (y_bus + y + np.sign(y_bus - y) * height / 2) / 2, label, fontsize=7.5, color=EDGE,
                va="center")


def draw_panel(ax, c: ModelConfig, title: str):
    psi, phi, omega = rows(c)
    counts = parameter_counts(c)
    ax.set_xlim(0, 100)
    ax.set_ylim(0, 37)
    ax.axis("off")
    ax.set_title(f"{title}: Ω {counts['gating']:,} + Φ {counts['motion']:,} + Ψ {counts['film']:,} parameters "
                 f"(K = {c.n_experts} experts, dropout {c.dropout})", fontsize=10.5, loc="left")
    p_psi = draw_chain(ax, psi, 31, 4, 96, COLOURS["Ψ"], 7.4)
    p_phi = draw_chain(ax, phi, 17.5, 0, 100, COLOURS["Φ"], 6.2)
    p_omega = draw_chain(ax, omega, 4, 0, 60, COLOURS["Ω"], 8.4)
    for y, text in ((35.2, "Ψ  FiLM generator (Eq. 2)"), (22.6, "Φ  motion synthesis (Eq. 3, 4)"),
                    (9.1, "Ω  gating network (Sec. 4.1)")):
        ax.text(0.5, y, text, fontsize=9.5, weight="bold")
    # γ, β of each hidden layer from Ψ's output down to the FiLM boxes of Φ; α up to every expert layer
    bus(ax, p_psi[-1], [p_phi[3], p_phi[7]], 25.8,
        [f"γ{l}, β{l}: {shape('B', c.hidden)} each" for l in (1, 2)], "#2f6b2f")
    bus(ax, p_omega[-1], [p_phi[1], p_phi[5], p_phi[9]], 11.2,
        [f"α {shape('B', c.n_experts)}: W = Σ_k α_k W_k"] + [f"α {shape('B', c.n_experts)}"] * 2, "#2b4c7e")


def save_small_png(fig, out: Path, colours: int = 48) -> None:
    """The figure as a PNG with a palette of a few colours (flat boxes and text): a third of the size."""
    from PIL import Image           # Pillow comes with matplotlib (the viz extra)
    buffer = io.BytesIO()
    fig.savefig(buffer, dpi=90)
    buffer.seek(0)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.open(buffer).convert("RGB").quantize(colors=colours).save(out, optimize=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "model_shapes.png")
    args = ap.parse_args()
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(18, 12))
    draw_panel(axes[0], small_config(), "The main job's model (ModelConfig.small, 100STYLE features)")
    draw_panel(axes[1], ModelConfig.paper(), "The paper's model (ModelConfig.paper)")
    fig.tight_layout()
    save_small_png(fig, args.out)
    plt.close(fig)
    print(f"wrote {args.out} ({args.out.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
