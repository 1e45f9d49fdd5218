"""Tests of wovenskin.training.models: shapes, contracts, causality, registry."""

from __future__ import annotations

import pytest
import torch

from wovenskin.training.models import (
    MODEL_REGISTRY,
    BiLSTM,
    ConvTransformer,
    TemporalConvNet,
    _CausalBlock,
    build_model,
    count_parameters,
    resolve_hparams,
    sinusoidal_encoding,
)

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

NAMES = tuple(MODEL_REGISTRY)


def test_registry_names() -> None:
    assert NAMES == ("transformer", "bilstm", "tcn")
    assert MODEL_REGISTRY["transformer"] is ConvTransformer
    assert MODEL_REGISTRY["bilstm"] is BiLSTM
    assert MODEL_REGISTRY["tcn"] is TemporalConvNet


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize(
    ("rows", "cols", "window", "n_classes"),
    [(10, 10, 30, 15), (6, 8, 30, 7), (3, 5, 12, 2), (1, 1, 4, 3), (7, 9, 17, 4)],
)
def test_logits_shape_for_any_grid_window_and_class_count(
    name: str, rows: int, cols: int, window: int, n_classes: int
) -> None:
    torch.manual_seed(0)
    model = build_model(name, rows, cols, window, n_classes).eval()
    for batch in (1, 5):
        logits = model(torch.randn(batch, window, rows, cols))
        assert logits.shape == (batch, n_classes)
        assert torch.isfinite(logits).all()


@pytest.mark.parametrize("name", NAMES)
def test_wrong_input_shape_is_refused_with_the_expected_shape(name: str) -> None:
    model = build_model(name, 10, 10, 30, 15)
    with pytest.raises(ValueError, match=r"expected windows of shape \(B, 30, 10, 10\)"):
        model(torch.zeros(2, 30, 6, 8))
    with pytest.raises(ValueError, match="got \\(30, 10, 10\\)"):
        model(torch.zeros(30, 10, 10))
    with pytest.raises(ValueError, match="expected windows"):
        model(torch.zeros(2, 29, 10, 10))


@pytest.mark.parametrize("name", NAMES)
def test_every_parameter_receives_a_gradient(name: str) -> None:
    torch.manual_seed(1)
    model = build_model(name, 6, 8, 20, 5).train()
    loss = model(torch.randn(3, 20, 6, 8)).logsumexp(dim=1).sum()
    loss.backward()
    unused = [n for n, p in model.named_parameters() if p.grad is None or not p.grad.any()]
    assert unused == []


@pytest.mark.parametrize("name", NAMES)
def test_input_scale_divides_the_input(name: str) -> None:
    torch.manual_seed(2)
    model = build_model(name, 6, 8, 10, 3).eval()
    x = torch.randn(4, 10, 6, 8)
    reference = model(x)
    model.set_input_scale(0.05)
    assert torch.allclose(model(x * 0.05), reference, atol=1e-5)
    assert "input_scale" in model.state_dict()
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="input scale"):
            model.set_input_scale(bad)


@pytest.mark.parametrize("name", NAMES)
def test_models_depend_on_frame_order(name: str) -> None:
    torch.manual_seed(3)
    model = build_model(name, 6, 8, 12, 4).eval()
    x = torch.randn(2, 12, 6, 8)
    assert not torch.allclose(model(x), model(x.flip(1)), atol=1e-4)


def test_models_depend_on_where_the_touch_is() -> None:
    # the stem keeps positions: the same blob at two places gives different embeddings
    torch.manual_seed(4)
    model = ConvTransformer(10, 10, 8, 3).eval()
    left = torch.zeros(1, 8, 10, 10)
    left[..., 5, 1] = 1.0
    right = torch.zeros(1, 8, 10, 10)
    right[..., 5, 8] = 1.0
    assert not torch.allclose(model(left), model(right), atol=1e-4)


def test_causal_block_never_looks_ahead() -> None:
    torch.manual_seed(5)
    block = _CausalBlock(dim=8, kernel=3, dilation=4, dropout=0.0).eval()
    x = torch.randn(1, 8, 30)
    changed = x.clone()
    changed[..., 20:] += torch.randn(1, 8, 10)
    assert torch.equal(block(x)[..., :20], block(changed)[..., :20])
    assert not torch.allclose(block(x)[..., 20:], block(changed)[..., 20:])


def test_tcn_receptive_field_covers_the_default_window() -> None:
    torch.manual_seed(6)
    # without the motion channel (whose window mean mixes all frames) only the blocks can
    # carry the first frame to the last time step
    model = TemporalConvNet(4, 4, 30, 3, motion_channel=False).eval()
    x = torch.zeros(1, 30, 4, 4)
    poked = x.clone()
    poked[0, 0, 2, 2] = 5.0
    features = model.stem(x).transpose(1, 2)
    features_poked = model.stem(poked).transpose(1, 2)
    assert torch.equal(features[..., 1:], features_poked[..., 1:])
    last = model.blocks(features)[..., -1]
    last_poked = model.blocks(features_poked)[..., -1]
    assert not torch.allclose(last, last_poked)


def test_sinusoidal_encoding() -> None:
    pe = sinusoidal_encoding(30, 64)
    assert pe.shape == (30, 64)
    assert torch.equal(pe[0, 0::2], torch.zeros(32))
    assert torch.equal(pe[0, 1::2], torch.ones(32))
    assert pe.abs().max() <= 1.0
    assert len({tuple(row.tolist()) for row in pe}) == 30  # every position distinct


def test_transformer_follows_the_paper_shape() -> None:
    model = ConvTransformer(10, 10, 30, 15)
    assert len(model.encoder.layers) == 4
    assert model.encoder.layers[0].self_attn.embed_dim == 64
    assert model.encoder.layers[0].self_attn.batch_first
    assert model.stem.project.out_features == 64
    assert model.head[-1].out_features == 15


def test_parameter_counts_are_small() -> None:
    counts = {n: count_parameters(build_model(n, 10, 10, 30, 15)) for n in NAMES}
    assert all(10_000 < c < 1_000_000 for c in counts.values()), counts
    assert counts["transformer"] < counts["bilstm"]


def test_build_model_refuses_unknown_names_and_hyperparameters() -> None:
    with pytest.raises(ValueError, match="unknown model 'gru'; known: transformer, bilstm, tcn"):
        build_model("gru", 10, 10, 30, 15)
    with pytest.raises(ValueError, match="unknown hyperparameter\\(s\\) depth"):
        build_model("transformer", 10, 10, 30, 15, depth=3)
    with pytest.raises(ValueError, match="divisible"):
        build_model("transformer", 10, 10, 30, 15, d_model=64, n_heads=5)
    with pytest.raises(ValueError, match="at least 2 classes"):
        build_model("tcn", 10, 10, 30, 1)
    with pytest.raises(ValueError, match="grid"):
        build_model("bilstm", 0, 10, 30, 15)


def test_build_model_passes_hyperparameters() -> None:
    model = build_model("bilstm", 6, 8, 30, 4, hidden=32, n_layers=1)
    assert model.lstm.hidden_size == 32 and model.lstm.num_layers == 1
    model = build_model("transformer", 6, 8, 30, 4, n_layers=2, ff_dim=64)
    assert len(model.encoder.layers) == 2


def test_resolve_hparams_completes_defaults() -> None:
    resolved = resolve_hparams("transformer", {"n_layers": 2})
    assert resolved["n_layers"] == 2
    assert resolved["d_model"] == 64
    assert set(resolved) == {
        "d_model",
        "n_layers",
        "n_heads",
        "ff_dim",
        "stem_channels",
        "dropout",
        "window_norm",
        "motion_channel",
        "level_input",
    }
    assert resolve_hparams("tcn") == resolve_hparams("tcn", {})
    rebuilt = build_model("tcn", 6, 8, 30, 4, **resolve_hparams("tcn"))
    assert count_parameters(rebuilt) == count_parameters(build_model("tcn", 6, 8, 30, 4))


def _zero_level_weights(model: torch.nn.Module) -> None:
    with torch.no_grad():
        if isinstance(model, BiLSTM):
            model.lstm.weight_ih_l0[:, -1] = 0.0
            model.lstm.weight_ih_l0_reverse[:, -1] = 0.0
        else:
            model.level.weight.zero_()


@pytest.mark.parametrize("name", NAMES)
def test_window_norm_separates_shape_from_strength(name: str) -> None:
    torch.manual_seed(7)
    model = build_model(name, 6, 8, 10, 3).eval()
    x = torch.randn(2, 10, 6, 8)
    with torch.inference_mode():
        # By default the output does not depend on strength at all (GESTURES.md: skins
        # differ 10x; finger count must come from shape), over a 30x range of gains.
        for gain in (0.3, 3.0, 10.0):
            assert torch.allclose(model(x), model(gain * x), atol=1e-5)
        # a window of tiny noise is not blown up to full scale: the floor holds it down
        quiet = 1e-4 * x
        assert not torch.allclose(model(quiet), model(x), atol=1e-4)
    # With the level as an input, strength reaches the network (the earlier design).
    torch.manual_seed(7)
    leveled = build_model(name, 6, 8, 10, 3, level_input=True).eval()
    with torch.inference_mode():
        assert not torch.allclose(leveled(x), leveled(3.0 * x), atol=1e-4)
        _zero_level_weights(leveled)
        assert torch.allclose(leveled(x), leveled(3.0 * x), atol=1e-5)


def test_without_window_norm_the_scale_reaches_the_network() -> None:
    torch.manual_seed(8)
    model = build_model("tcn", 6, 8, 10, 3, window_norm=False).eval()
    x = torch.randn(2, 10, 6, 8)
    with torch.inference_mode():
        assert not torch.allclose(model(x), model(3.0 * x), atol=1e-4)


def test_motion_channel_shows_which_way_a_blob_moves() -> None:
    from wovenskin.training.models import FrameStem

    stem = FrameStem(6, 8, channels=4, embed_dim=16)
    window = torch.zeros(1, 10, 6, 8)
    for t in range(10):
        window[0, t, 3, 2 + t // 2] = 1.0  # a contact moving right
    captured = {}
    stem.conv1.register_forward_hook(lambda m, args, out: captured.update(x=args[0]))
    assert stem(window).shape == (1, 10, 16)
    frames, deviation = captured["x"][:, 0], captured["x"][:, 1]
    assert torch.equal(frames, window[0])
    assert deviation[0, 3, 2] > 0 and deviation[0, 3, 6] < 0  # early: here, not there yet
    assert deviation[9, 3, 6] > 0 and deviation[9, 3, 2] < 0  # late: there, gone from here
    assert torch.allclose(deviation.sum(dim=0), torch.zeros(6, 8), atol=1e-6)
