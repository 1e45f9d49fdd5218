"""Starting a model from another's weights with new classes or another grid."""

from __future__ import annotations

import pytest
import torch

from wovenskin.errors import ConfigError
from wovenskin.training.models import build_model
from wovenskin.training.transfer import merged_classes, transferred_model

HP = {"d_model": 16, "n_layers": 1, "n_heads": 2, "ff_dim": 32, "stem_channels": 4}
BASE = ["swipe_up", "push", "invalid"]


def _base(rows: int = 10, cols: int = 10):
    torch.manual_seed(0)
    model = build_model("transformer", rows, cols, 30, len(BASE), **HP)
    model.set_input_scale(0.05)
    return model.eval()


def test_merged_classes_insert_new_ones_before_invalid():
    assert merged_classes(BASE, ["double_tap", "push", "l_stroke"]) == [
        "swipe_up", "push", "double_tap", "l_stroke", "invalid",
    ]  # fmt: skip
    with pytest.raises(ConfigError):
        merged_classes(["a", "b"], ["c"])


def test_a_new_class_keeps_every_known_class_score():
    base = _base()
    classes = merged_classes(BASE, ["double_tap"])
    model, transfer = transferred_model(base, BASE, "transformer", HP, classes, 10, 10, 30)
    assert transfer.new_classes == ("double_tap",) and not transfer.reinitialised
    x = torch.randn(4, 30, 10, 10) * 0.05
    with torch.no_grad():
        old, new = base(x), model.eval()(x)
    for i, name in enumerate(BASE):
        assert torch.allclose(old[:, i], new[:, classes.index(name)], atol=1e-5)
    assert float(model.input_scale) == pytest.approx(0.05)


def test_another_grid_keeps_all_but_the_stem_projection():
    base = _base()
    model, transfer = transferred_model(base, BASE, "transformer", HP, BASE, 8, 8, 30)
    assert transfer.reinitialised == ("stem.project",)
    assert torch.equal(model.stem.conv1.weight, base.stem.conv1.weight)
    ours, theirs = model.encoder.layers[0].linear1, base.encoder.layers[0].linear1
    assert torch.equal(ours.weight, theirs.weight)
    assert model(torch.zeros(2, 30, 8, 8)).shape == (2, 3)


def test_dropping_a_class_or_changing_the_window_is_refused():
    base = _base()
    with pytest.raises(ConfigError, match="drops"):
        transferred_model(base, BASE, "transformer", HP, ["push", "invalid"], 10, 10, 30)
    with pytest.raises(ConfigError, match="window"):
        transferred_model(base, BASE, "transformer", HP, BASE, 10, 10, 20)
