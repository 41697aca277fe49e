"""Every size of the style model in one dataclass (Sec. 4.2-4.3 of the paper).

``ModelConfig.paper()`` reproduces the network of the paper / the released code:

    Φ  motion network   x 348 -> 512 -> 512 -> z 342, K = 8 gated experts per layer
    Ω  gating network   phases 8 -> 32 -> 32 -> K
    Ψ  FiLM generator   clip 240 frames x 300 features -> conv1d(256, k=25) -> pool 2
                        -> conv1d(256, k=25) -> pool 2 -> dense 2048 -> dense 4*512

``ModelConfig.small(...)`` keeps the structure at the size of the main job (examples/train_small.py,
about 0.7 M parameters for 100STYLE's features) and ``ModelConfig.tiny()`` at toy sizes for tests.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields


#: the largest model allowed (about 1 GiB of float32 weights; the paper's has 44 million)
MAX_PARAMETERS = 250_000_000


@dataclass(frozen=True)
class ModelConfig:
    """Sizes and options of Ω, Φ and Ψ.

    x_dim, z_dim        input / output feature sizes of Φ (Sec. 3.2)
    phase_dim           local-phase input of Ω: 4 end effectors x (sin, cos) (Eq. 1)
    n_experts           K, experts blended per layer of Φ
    hidden              width of both hidden layers of Φ (= size of each FiLM vector)
    gating_hidden       width of both hidden layers of Ω
    clip_frames         T, frames of the style clip fed to Ψ
    clip_channels       C, features per clip frame
    conv_filters        filters of both conv1d layers of Ψ
    conv_kernel         temporal kernel size (odd: 'same' padding)
    film_dense          hidden dense width of Ψ
    dropout             drop probability in training (0.3 in the paper), before every layer of Ω
                        and Φ and before Ψ's last dense layer (film_generator.py)
    ln_unbiased, ln_eps layer-norm convention used in training: (x-μ)/(σ+eps), σ unbiased
                        (the original training code); the released runtime uses (False, 0.0)
    """

    x_dim: int = 348
    z_dim: int = 342
    phase_dim: int = 8
    n_experts: int = 8
    hidden: int = 512
    gating_hidden: int = 32
    clip_frames: int = 240
    clip_channels: int = 300
    conv_filters: int = 256
    conv_kernel: int = 25
    film_dense: int = 2048
    dropout: float = 0.3
    ln_unbiased: bool = True
    ln_eps: float = 1e-6

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type in ("int", int) and (not isinstance(value, int) or value <= 0):
                raise ValueError(f"ModelConfig.{f.name} must be a positive int, got {value!r}")
        if self.conv_kernel % 2 != 1:
            raise ValueError(f"ModelConfig.conv_kernel must be odd ('same' padding), got {self.conv_kernel}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"ModelConfig.dropout must be in [0, 1), got {self.dropout}")
        if self.pooled_frames < 1:
            raise ValueError(f"ModelConfig.clip_frames={self.clip_frames} is too short for two 2x poolings")
        if not (isinstance(self.ln_eps, (int, float)) and 0.0 <= self.ln_eps < 1.0):
            raise ValueError(f"ModelConfig.ln_eps must be in [0, 1), got {self.ln_eps!r}")
        n = self.n_parameters
        if n > MAX_PARAMETERS:      # before anything is allocated: a typo must not ask for 600 GiB
            raise ValueError(f"ModelConfig: these sizes make {n:,} parameters ({4 * n / 2**30:.1f} GiB in float32, "
                             f"more with the optimiser's moments); at most {MAX_PARAMETERS:,} are allowed "
                             f"(the paper's model has 44 million)")

    # ---- derived sizes -------------------------------------------------------------------
    @property
    def n_parameters(self) -> int:
        """Ω + Φ + Ψ parameters, from the sizes alone (model/style_model.py::parameter_counts counts
        the same from the networks' shapes)."""
        K, H, G = self.n_experts, self.hidden, self.gating_hidden
        gating = self.phase_dim * G + G + G * G + G + G * K + K
        motion = K * (self.x_dim * H + H + H * H + H + H * self.z_dim + self.z_dim)
        k, C, Fn = self.conv_kernel, self.clip_channels, self.conv_filters
        film = (k * C * Fn + Fn + k * Fn * Fn + Fn + self.flat_dim * self.film_dense + self.film_dense
                + self.film_dense * self.film_dim + self.film_dim)
        return int(gating + motion + film)

    @property
    def film_dim(self) -> int:
        """Length of Ψ's output {γ1, β1, γ2, β2} (Eq. 2) = parameters per style at run time."""
        return 4 * self.hidden

    @property
    def pooled_frames(self) -> int:
        """Frames left after the two max-pool layers (floor division each time)."""
        return (self.clip_frames // 2) // 2

    @property
    def flat_dim(self) -> int:
        """Input size of Ψ's first dense layer (pooled frames x filters)."""
        return self.pooled_frames * self.conv_filters

    # ---- presets -------------------------------------------------------------------------
    @classmethod
    def paper(cls) -> "ModelConfig":
        """The configuration of the paper and the released network."""
        return cls()

    @classmethod
    def small(cls, x_dim: int, z_dim: int, clip_frames: int, clip_channels: int, phase_dim: int = 8,
              **overrides) -> "ModelConfig":
        """The main job's model: the paper's structure with K = 4 experts, hidden 128, Ω 32-32, and
        Ψ with 32 filters of width 9 and a 128-wide dense layer (707,420 parameters for 100STYLE's
        features and 120-frame clips). Dropout 0.2 rather than the paper's 0.3 on a 4x narrower
        network: measured in 60 s rollouts, every style keeps stepping (0.3 and 0.1 left some
        in a frozen pose sliding along the path; benchmarks/trained_rollout.py). The feature
        sizes come from the data (a FeatureLayout) and the clip length from the dataset."""
        sizes = dict(x_dim=x_dim, z_dim=z_dim, phase_dim=phase_dim, clip_frames=clip_frames,
                     clip_channels=clip_channels, n_experts=4, hidden=128, gating_hidden=32,
                     conv_filters=32, conv_kernel=9, film_dense=128, dropout=0.2)
        sizes.update(overrides)
        return cls(**sizes)

    @classmethod
    def tiny(cls, x_dim: int = 24, z_dim: int = 20, clip_channels: int = 12, **overrides) -> "ModelConfig":
        """Toy sizes with the paper's structure, for tests and gradient checks."""
        sizes = dict(x_dim=x_dim, z_dim=z_dim, phase_dim=8, n_experts=4, hidden=16, gating_hidden=8,
                     clip_frames=16, clip_channels=clip_channels, conv_filters=8, conv_kernel=5,
                     film_dense=32)
        sizes.update(overrides)
        return cls(**sizes)

    # ---- serialisation (checkpoints store the config as JSON) ----------------------------
    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ModelConfig":
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            more = f" and {len(unknown) - 5:,} more" if len(unknown) > 5 else ""     # one line, whatever a file holds
            raise ValueError(f"ModelConfig.from_dict: unknown field(s) {[u[:40] for u in unknown[:5]]}{more}")
        return cls(**d)
