"""Gesture classifiers over windows of tactile frames (PyTorch), and their registry.

Every model maps a batch of windows ``(B, W, R, C)`` float32 -- ``W`` conditioned frames of
an ``R x C`` skin, indexed ``[row, col]`` -- to logits ``(B, K)`` over ``K`` classes. Grid
size, window length and class count are constructor arguments, so any skin and any class
list work; a model only accepts the grid and window it was built for.

- :class:`ConvTransformer`, the paper's model: a convolutional stem (:class:`FrameStem`)
  turns every frame into a 64-d embedding, sinusoidal positional encoding marks the
  frame's place in the window, four transformer encoder layers mix the frames, mean
  pooling and an MLP head classify.
- :class:`BiLSTM`, the paper's baseline: a bidirectional LSTM over flattened frames.
- :class:`TemporalConvNet`, the third baseline: the same per-frame stem followed by
  residual blocks of dilated causal 1-D convolutions over time. Dilations 1, 2, 4, 8 with
  kernel 3 give a receptive field of 31 frames, the whole default window, in four cheap
  layers (a 3D-CNN needs depth or large kernels to see as far, which the paper names as its
  weakness), and every op is a plain convolution that ONNX Runtime runs fast on one thread.

The transformer and the TCN embed frames the same way, through :class:`StemClassifier`.

Input normalisation, shared by all models: windows are divided by ``input_scale``, a
buffer (saved in the state dict and baked into the ONNX graph) that training sets to the
typical window peak of its data (``set_input_scale``). With ``window_norm`` (default) each
window is then divided by its own peak |value| (floored at :data:`PEAK_FLOOR`). The
strength of a touch varies by two orders of magnitude across skins and people (fabric
sensitivity, pressure, finger size) while its shape and motion carry the class, so the
network sees the shape at a fixed scale. With ``level_input`` the log of the peak, the
window's *level*, is also given to the network as one number; it is off by default:
given the level, a network trained on a few skins learns strength as a cue (a stronger
skin's one-finger swipe reads as two fingers), which docs/gestures.md rules out. Without it
a model's output is the same for a window and that window times any gain that keeps its
peak above the floor (a property the tests check).

:func:`build_model` creates a model from a registry name (``"transformer"``, ``"bilstm"``,
``"tcn"``) and hyperparameters; :func:`resolve_hparams` completes hyperparameters with the
model's defaults, so a checkpoint pins every one of them.  A new model is one
:class:`WindowClassifier` subclass and one :data:`MODEL_REGISTRY` entry.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping
from typing import Any

import torch
from torch import nn

from wovenskin.errors import ConfigError


def _check_dims(rows: int, cols: int, window: int, n_classes: int) -> None:
    if rows < 1 or cols < 1:
        raise ValueError(f"grid needs at least one row and column, got {rows}x{cols}")
    if window < 1:
        raise ValueError(f"window needs at least one frame, got {window}")
    if n_classes < 2:
        raise ValueError(f"a classifier needs at least 2 classes, got {n_classes}")


PEAK_FLOOR = 0.02
"""Smallest divisor of window normalisation, as a fraction of ``input_scale``."""
LEVEL_EPS = 1e-3
"""Added to the normalised peak before the log that gives the window level."""


class WindowClassifier(nn.Module):
    """Base of all models: the grid/window contract, input scale and window normalisation.

    A new model derives from it, takes ``(rows, cols, window, n_classes, **hparams)`` with
    a default for every hyperparameter, calls :meth:`_normalized` first in ``forward``,
    and gets one entry in :data:`MODEL_REGISTRY`: training, comparison, checkpoints, the
    ONNX export and the benchmarks then know it by that name.
    """

    def __init__(
        self,
        rows: int,
        cols: int,
        window: int,
        n_classes: int,
        window_norm: bool,
        level_input: bool = False,
    ) -> None:
        super().__init__()
        _check_dims(rows, cols, window, n_classes)
        self.rows = rows
        self.cols = cols
        self.window = window
        self.n_classes = n_classes
        self.window_norm = window_norm
        self.level_input = level_input
        self.register_buffer("input_scale", torch.ones(()))

    def set_input_scale(self, scale: float) -> None:
        """Set the divisor applied to every input (a typical peak of the training windows)."""
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"input scale must be positive and finite, got {scale}")
        self.input_scale.fill_(float(scale))

    def _normalized(self, windows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Checked and normalised windows ``(B, W, R, C)`` and their levels ``(B, 1)``."""
        expected = (self.window, self.rows, self.cols)
        tracing = torch.jit.is_tracing()  # shapes are symbolic while exporting to ONNX
        if not tracing and (windows.dim() != 4 or tuple(windows.shape[1:]) != expected):
            raise ValueError(
                f"expected windows of shape (B, {self.window}, {self.rows}, {self.cols}), "
                f"got {tuple(windows.shape)}"
            )
        x = windows / self.input_scale
        if not self.window_norm:
            return x, torch.zeros_like(x[:, 0, 0, :1])
        peak = x.abs().amax(dim=(1, 2, 3), keepdim=True)
        level = torch.log(peak + LEVEL_EPS).reshape(-1, 1)
        return x / torch.clamp(peak, min=PEAK_FLOOR), level


class FrameStem(nn.Module):
    """Per-frame convolutional encoder: windows ``(B, W, R, C)`` to embeddings ``(B, W, D)``.

    A 3x3 convolution at full resolution, a strided 3x3 convolution that halves the grid
    (rounding up), both with ReLU (which ONNX Runtime fuses into the convolution and which
    trained better than GELU here), then a linear map of the flattened feature map and a
    layer norm. The
    flattened map keeps where on the skin each feature is, which the direction of a swipe
    depends on; its size follows from the grid, so any ``R x C`` works.

    With ``motion_channel`` every frame comes with a second channel, its deviation from the
    window's mean frame. Within 150 ms a smoothed contact moves by a fraction of a channel;
    in the frame itself that is a slight change of a blob, in the deviation it is a
    negative lobe behind and a positive lobe ahead, which a 3x3 convolution reads directly.
    """

    def __init__(
        self, rows: int, cols: int, channels: int, embed_dim: int, motion_channel: bool = True
    ) -> None:
        super().__init__()
        self.rows = rows
        self.cols = cols
        self.motion_channel = motion_channel
        in_channels = 2 if motion_channel else 1
        self.conv1 = nn.Conv2d(in_channels, channels, kernel_size=3, padding=1)
        self.conv2 = nn.Conv2d(channels, channels, kernel_size=3, stride=2, padding=1)
        reduced = math.ceil(rows / 2) * math.ceil(cols / 2)
        self.project = nn.Linear(channels * reduced, embed_dim)
        self.norm = nn.LayerNorm(embed_dim)
        self.act = nn.ReLU()

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        batch, window = windows.shape[0], windows.shape[1]
        if self.motion_channel:
            deviation = windows - windows.mean(dim=1, keepdim=True)
            x = torch.stack([windows, deviation], dim=2).reshape(-1, 2, self.rows, self.cols)
        else:
            x = windows.reshape(-1, 1, self.rows, self.cols)
        x = self.act(self.conv1(x))
        x = self.act(self.conv2(x))
        return self.norm(self.project(x.flatten(1))).reshape(batch, window, -1)


def sinusoidal_encoding(length: int, dim: int) -> torch.Tensor:
    """The ``(length, dim)`` sine/cosine positional encoding of Vaswani et al. (2017)."""
    position = torch.arange(length, dtype=torch.float32).unsqueeze(1)
    frequency = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32) * (-math.log(1e4) / dim))
    encoding = torch.zeros(length, dim)
    encoding[:, 0::2] = torch.sin(position * frequency)
    encoding[:, 1::2] = torch.cos(position * frequency[: dim // 2])
    return encoding


class StemClassifier(WindowClassifier):
    """A :class:`WindowClassifier` whose frames are embedded one by one by a
    :class:`FrameStem`, with the window level (``level_input``) added to every embedding.

    A subclass calls :meth:`_add_stem` in its constructor and :meth:`_frame_embeddings`
    first in ``forward``.
    """

    stem: FrameStem
    level: nn.Linear | None

    def _add_stem(self, channels: int, embed_dim: int, motion_channel: bool) -> None:
        """Create ``stem`` and, with ``level_input``, ``level`` (level -> embedding)."""
        self.stem = FrameStem(self.rows, self.cols, channels, embed_dim, motion_channel)
        self.level = nn.Linear(1, embed_dim) if self.level_input else None

    def _frame_embeddings(
        self, windows: torch.Tensor, positions: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Embeddings ``(B, W, D)`` of the normalised frames of ``windows``, plus
        ``positions`` ``(W, D)`` if given, then the level's embedding if used."""
        x, level = self._normalized(windows)
        frames = self.stem(x)
        if positions is not None:
            frames = frames + positions
        if self.level is not None:
            frames = frames + self.level(level).unsqueeze(1)
        return frames


class ConvTransformer(StemClassifier):
    """Convolutional stem per frame, positional encoding, transformer encoder, MLP head.

    Dropout is off by default: the training set is large and seen only about three times,
    so it did not overfit, and on one CPU thread dropout's random masks cost a quarter of
    a training step's time (621 vs 496 windows/s measured on the project's machine).
    """

    def __init__(
        self,
        rows: int,
        cols: int,
        window: int,
        n_classes: int,
        d_model: int = 64,
        n_layers: int = 4,
        n_heads: int = 4,
        ff_dim: int = 128,
        stem_channels: int = 16,
        dropout: float = 0.0,
        window_norm: bool = True,
        motion_channel: bool = True,
        level_input: bool = False,
    ) -> None:
        super().__init__(rows, cols, window, n_classes, window_norm, level_input)
        if d_model % n_heads or d_model % 2:
            raise ValueError(f"d_model {d_model} must be even and divisible by n_heads {n_heads}")
        self._add_stem(stem_channels, d_model, motion_channel)
        self.register_buffer("positions", sinusoidal_encoding(window, d_model))
        layer = nn.TransformerEncoderLayer(
            d_model,
            n_heads,
            dim_feedforward=ff_dim,
            dropout=dropout,
            activation="gelu",
            batch_first=True,
            norm_first=True,
        )
        self.encoder = nn.TransformerEncoder(
            layer, n_layers, norm=nn.LayerNorm(d_model), enable_nested_tensor=False
        )
        self.head = nn.Sequential(
            nn.Linear(d_model, d_model),
            nn.GELU(),
            nn.Dropout(dropout),
            nn.Linear(d_model, n_classes),
        )

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        encoded = self.encoder(self._frame_embeddings(windows, self.positions))
        return self.head(encoded.mean(dim=1))


class BiLSTM(WindowClassifier):
    """Bidirectional LSTM over flattened frames (plus the window level); mean of the top
    layer's outputs -> linear."""

    def __init__(
        self,
        rows: int,
        cols: int,
        window: int,
        n_classes: int,
        hidden: int = 128,
        n_layers: int = 2,
        dropout: float = 0.1,
        window_norm: bool = True,
        level_input: bool = False,
    ) -> None:
        super().__init__(rows, cols, window, n_classes, window_norm, level_input)
        self.lstm = nn.LSTM(
            rows * cols + int(level_input),
            hidden,
            num_layers=n_layers,
            batch_first=True,
            bidirectional=True,
            dropout=dropout if n_layers > 1 else 0.0,
        )
        self.dropout = nn.Dropout(dropout)
        self.head = nn.Linear(2 * hidden, n_classes)

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        x, level = self._normalized(windows)
        steps = x.flatten(2)
        if self.level_input:
            steps = torch.cat([steps, level.unsqueeze(1).expand(-1, self.window, 1)], dim=2)
        outputs, _ = self.lstm(steps)
        return self.head(self.dropout(outputs.mean(dim=1)))


class _CausalBlock(nn.Module):
    """Two dilated causal convolutions with a residual connection, on ``(B, D, W)``."""

    def __init__(self, dim: int, kernel: int, dilation: int, dropout: float) -> None:
        super().__init__()
        self.pad = (kernel - 1) * dilation
        self.conv1 = nn.Conv1d(dim, dim, kernel, dilation=dilation)
        self.conv2 = nn.Conv1d(dim, dim, kernel, dilation=dilation)
        self.act = nn.GELU()
        self.dropout = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.act(self.conv1(nn.functional.pad(x, (self.pad, 0))))
        y = self.dropout(y)
        y = self.conv2(nn.functional.pad(y, (self.pad, 0)))
        return self.act(x + self.dropout(y))


class TemporalConvNet(StemClassifier):
    """Per-frame stem, dilated causal residual blocks over time, last step -> MLP head."""

    def __init__(
        self,
        rows: int,
        cols: int,
        window: int,
        n_classes: int,
        dim: int = 64,
        n_blocks: int = 4,
        kernel: int = 3,
        stem_channels: int = 32,
        dropout: float = 0.1,
        window_norm: bool = True,
        motion_channel: bool = True,
        level_input: bool = False,
    ) -> None:
        super().__init__(rows, cols, window, n_classes, window_norm, level_input)
        self._add_stem(stem_channels, dim, motion_channel)
        self.blocks = nn.Sequential(
            *(_CausalBlock(dim, kernel, 2**i, dropout) for i in range(n_blocks))
        )
        self.head = nn.Sequential(
            nn.Linear(2 * dim, dim), nn.GELU(), nn.Dropout(dropout), nn.Linear(dim, n_classes)
        )

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        encoded = self.blocks(self._frame_embeddings(windows).transpose(1, 2))
        pooled = torch.cat([encoded[:, :, -1], encoded.mean(dim=2)], dim=1)
        return self.head(pooled)


MODEL_REGISTRY: dict[str, type[WindowClassifier]] = {
    "transformer": ConvTransformer,
    "bilstm": BiLSTM,
    "tcn": TemporalConvNet,
}
"""Registry names -> model classes, in the order the comparison table lists them; the
one place a model is named (``wovenskin train --model``, ``compare --models``)."""


def build_model(
    name: str, rows: int, cols: int, window: int, n_classes: int, **hparams: Any
) -> nn.Module:
    """Build registry model ``name`` for a ``rows x cols`` grid, ``window``, ``n_classes``."""
    resolve_hparams(name, hparams)  # refuses unknown models and hyperparameter names
    return MODEL_REGISTRY[name](rows, cols, window, n_classes, **hparams)


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


_SHAPE_ARGUMENTS = ("rows", "cols", "window", "n_classes")


def resolve_hparams(name: str, hparams: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """``hparams`` completed with the defaults of model ``name``; unknown names are refused."""
    if name not in MODEL_REGISTRY:
        raise ConfigError(f"unknown model {name!r}; known: {', '.join(MODEL_REGISTRY)}")
    parameters = inspect.signature(MODEL_REGISTRY[name]).parameters
    defaults = {
        key: p.default
        for key, p in parameters.items()
        if key not in _SHAPE_ARGUMENTS and p.default is not inspect.Parameter.empty
    }
    given = dict(hparams or {})
    unknown = sorted(set(given) - set(defaults))
    if unknown:
        raise ConfigError(
            f"unknown hyperparameter(s) {', '.join(unknown)} for model {name!r}; "
            f"known: {', '.join(defaults)}"
        )
    return {**defaults, **given}
