"""The network toolkit shared by MLPs and GNNs: the Adam update both train with, numpy
layers against torch layers, saving layers, and floored standardisation."""

import numpy as np
import pytest
import torch

from bpns.baselines import gnn
from bpns.nets import layers as nets
from bpns.nets import mlp


def _params(dtype=torch.float64) -> list[torch.Tensor]:
    gen = torch.Generator().manual_seed(0)
    return [torch.randn(s, generator=gen, dtype=dtype) for s in ((3, 4), (4,), (4, 2), (2,))]


def test_adam_follows_torch_adam_on_several_tensors_over_many_steps():
    ours = _params()
    theirs = [p.clone().requires_grad_(True) for p in ours]
    adam, ref = nets.Adam(ours, lr=1e-2), torch.optim.Adam(theirs, lr=1e-2)
    gen = torch.Generator().manual_seed(1)
    for _ in range(200):
        grads = [torch.randn(p.shape, generator=gen, dtype=p.dtype) for p in ours]
        for p, g in zip(theirs, grads, strict=True):
            p.grad = g.clone()
        ref.step()
        adam.step(grads)
    for a, b in zip(ours, theirs, strict=True):
        # equal to rounding: torch's bias correction takes x ** 0.5, ours math.sqrt(x)
        np.testing.assert_allclose(a.numpy(), b.detach().numpy(), rtol=1e-12, atol=1e-14)
    assert not torch.equal(ours[0], _params()[0])  # it did move


def test_adam_leaves_a_parameter_without_gradient_as_it_is_and_still_counts_the_step():
    params = _params()
    before = [p.clone() for p in params]
    adam = nets.Adam(params, lr=0.1)
    adam.step([torch.ones_like(params[0]), None, None, torch.ones_like(params[3])])
    assert torch.equal(params[1], before[1]) and torch.equal(params[2], before[2])
    # first step: m / sqrt(v) is the gradient's sign, so every entry moves by lr
    np.testing.assert_allclose((before[0] - params[0]).numpy(), 0.1, rtol=1e-6)
    assert adam.t == 1


def test_both_network_kinds_train_with_the_one_toolkit():
    assert mlp.Adam is gnn.Adam is nets.Adam
    assert mlp.standardisation is gnn.standardisation is nets.standardisation
    assert mlp.numpy_mlp is gnn.numpy_mlp is nets.numpy_mlp


def test_numpy_layers_compute_what_the_torch_layers_compute():
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(3)
        layers = nets.torch_linears((5, 8, 8, 3)).double()
    x = np.random.default_rng(0).normal(size=(7, 5))
    ours = nets.numpy_mlp(nets.numpy_layers(layers), x)
    with torch.no_grad():
        ref = nets.torch_mlp(layers, torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=1e-12)
    back = nets.torch_layers(nets.numpy_layers(layers))
    with torch.no_grad():
        np.testing.assert_array_equal(nets.torch_mlp(back, torch.from_numpy(x)).numpy(), ref)


def test_layers_round_trip_through_named_arrays_under_a_prefix():
    rng = np.random.default_rng(0)
    layers = tuple((rng.normal(size=(a, b)), rng.normal(size=b)) for a, b in ((4, 3), (3, 2)))
    arrays = {**nets.layers_to_arrays(layers, "enc/"), "other/w0": np.zeros((1, 1))}
    assert nets.count_layers(arrays, "enc/") == 2
    back = nets.layers_from_arrays(arrays, "enc/")
    assert all(
        np.array_equal(w, w2) and np.array_equal(b, b2)
        for (w, b), (w2, b2) in zip(layers, back, strict=True)
    )
    assert nets.layers_from_arrays(arrays, "dec/") == ()
    del arrays["enc/b1"]
    with pytest.raises(KeyError):
        nets.layers_from_arrays(arrays, "enc/")


def test_standardisation_floors_the_std_of_nearly_constant_columns():
    data = np.array([[0.0, 5.0], [2.0, 5.0 + 1e-9]])
    mean, std = nets.standardisation(data, std_floor=0.01)
    np.testing.assert_array_equal(mean, [1.0, data[:, 1].mean()])
    np.testing.assert_array_equal(std, [1.0, 0.01])


def test_layer_shapes_must_chain_from_the_input_width():
    layers = ((np.zeros((4, 3)), np.zeros(3)), (np.zeros((3, 2)), np.zeros(2)))
    assert nets.check_layers(layers, 4, "net") == 2
    with pytest.raises(ValueError, match=r"net: layer 0 has shapes \(4, 3\), \(3,\); expected \(5"):
        nets.check_layers(layers, 5, "net")
    broken = (layers[0], (np.zeros((2, 2)), np.zeros(2)))
    with pytest.raises(ValueError, match="layer 1"):
        nets.check_layers(broken, 4, "net")
