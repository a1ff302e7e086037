"""Networks: torch training with hand-written gradients, numpy inference."""

import numpy as np
import pytest
import torch

from bpns.learning.config import MLPConfig
from bpns.nets import mlp

FAST = MLPConfig(num_steps=300, batch_size=64)


@pytest.fixture(autouse=True)
def _one_torch_thread():
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _data(seed=0, n=400):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 5)) * [1.0, 10.0, 0.1, 1.0, 3.0] + [0.0, 5.0, -1.0, 2.0, 0.0]
    y = np.stack([x[:, 0] - 0.2 * x[:, 1], 3.0 * x[:, 2] + 1.0], axis=1)
    return x, y


@pytest.mark.parametrize(
    "loss",
    [mlp.MSELoss(), mlp.GaussianNLLLoss(), mlp.WeightedBCELoss(3.0)],
    ids=["mse", "gaussian", "bce"],
)
def test_hand_written_gradients_match_autograd(loss):
    torch.manual_seed(0)
    out = 4
    net = mlp._FlatMLP((5, 8, 8, out), seed=1, dtype=torch.float64)
    x = torch.randn(16, 5, dtype=torch.float64)
    t = torch.randn(16, out // 2 if isinstance(loss, mlp.GaussianNLLLoss) else out)
    t = (t > 0).double() if isinstance(loss, mlp.WeightedBCELoss) else t.double()
    with torch.no_grad():
        acts = net.forward(x)
        net.backward(acts, loss.grad(acts[-1], t))
    flat = net.flat.clone().requires_grad_(True)
    h, offset = x, 0
    for k, (w, b) in enumerate(zip(net.weights, net.biases, strict=True)):
        wv = flat[offset : offset + w.numel()].view(w.shape)
        offset += w.numel()
        bv = flat[offset : offset + b.numel()]
        offset += b.numel()
        h = h @ wv + bv
        h = torch.relu(h) if k < len(net.weights) - 1 else h
    loss.value(h, t).backward()
    np.testing.assert_allclose(net.grad.numpy(), flat.grad.numpy(), rtol=1e-9, atol=1e-12)


def test_numpy_inference_matches_torch_forward():
    x, y = _data()
    reg = mlp.train_regressor(x, y, FAST, seed=0)
    ref = mlp.torch_reference(reg, x) * reg.output_std + reg.output_mean
    np.testing.assert_allclose(mlp.Regressor(reg)(x), ref, atol=1e-6)
    for row, expected in zip(x[:5], ref[:5], strict=True):  # single vectors as well
        np.testing.assert_allclose(mlp.Regressor(reg)(row), expected, atol=1e-6)

    gauss = mlp.train_gaussian(x, y, FAST, seed=0)
    mean_t, var_t = mlp.torch_gaussian_head(torch.from_numpy(mlp.torch_reference(gauss, x)))
    mean, std = mlp.GaussianRegressor(gauss).mean_std(x)
    np.testing.assert_allclose(
        mean, mean_t.numpy() * gauss.output_std + gauss.output_mean, atol=1e-6
    )
    np.testing.assert_allclose(std, np.sqrt(var_t.numpy()) * gauss.output_std, atol=1e-6)

    labels = (x[:, 0] > 0).astype(float)
    cls = mlp.train_classifier(x, labels, FAST, seed=0)
    prob_t = torch.sigmoid(torch.from_numpy(mlp.torch_reference(cls, x)))[:, 0].numpy()
    np.testing.assert_allclose(mlp.BinaryClassifier(cls).prob(x), prob_t, atol=1e-6)


def test_same_seed_gives_identical_weights_and_other_seeds_differ():
    x, y = _data()
    a = mlp.train_regressor(x, y, FAST, seed=3)
    b = mlp.train_regressor(x, y, FAST, seed=3)
    c = mlp.train_regressor(x, y, FAST, seed=4)
    assert a.identical(b)
    assert not a.identical(c)


def test_training_does_not_disturb_torch_global_rng():
    torch.manual_seed(123)
    expected = torch.rand(3)
    torch.manual_seed(123)
    mlp.train_regressor(*_data(), FAST, seed=0)
    assert torch.equal(torch.rand(3), expected)


def test_regressor_fits_a_linear_map_on_unstandardised_data():
    x, y = _data(n=2000)
    params = mlp.train_regressor(x, y, MLPConfig(num_steps=1500, batch_size=128), seed=0)
    xt, yt = _data(seed=1, n=200)
    err = np.abs(mlp.Regressor(params)(xt) - yt)
    assert np.median(err / y.std(axis=0)) < 0.05


def test_gaussian_learns_the_noise_level():
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, size=(2000, 1))
    y = 2.0 * x + rng.normal(scale=0.3, size=x.shape)
    params = mlp.train_gaussian(x, y, MLPConfig(num_steps=1500, batch_size=128), seed=0)
    mean, std = mlp.GaussianRegressor(params).mean_std(np.array([[0.5], [-0.5]]))
    np.testing.assert_allclose(mean[:, 0], [1.0, -1.0], atol=0.1)
    np.testing.assert_allclose(std[:, 0], 0.3, rtol=0.25)


def test_classifier_separates_classes_despite_imbalance():
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, size=(1000, 2))
    labels = (x[:, 0] + x[:, 1] > 1.0).astype(float)  # ~12% positives
    params = mlp.train_classifier(x, labels, MLPConfig(num_steps=1500, batch_size=128), seed=0)
    prob = mlp.BinaryClassifier(params).prob(np.array([[0.9, 0.9], [-0.5, 0.0]]))
    assert prob[0] > 0.5 > prob[1]
    with pytest.raises(ValueError, match="both classes"):
        mlp.train_classifier(x, np.ones(len(x)), FAST, seed=0)


def test_nearly_constant_columns_are_not_amplified():
    x, y = _data()
    x[:, 2] = 7.0 + 1e-4 * np.random.default_rng(1).standard_normal(len(x))  # jitter only
    params = mlp.train_regressor(x, y, FAST, seed=0)
    assert params.input_std[2] == FAST.std_floor
    shifted = x[:3].copy()
    shifted[:, 2] += 1e-3
    diff = mlp.Regressor(params)(shifted) - mlp.Regressor(params)(x[:3])
    assert np.all(np.abs(diff) < 1.0)


def test_params_round_trip_through_arrays():
    params = mlp.train_gaussian(*_data(), FAST, seed=0)
    back = mlp.MLPParams.from_arrays(params.to_arrays("g/"), "g/")
    assert back.identical(params)


def test_non_finite_inputs_propagate():
    params = mlp.train_regressor(*_data(), FAST, seed=0)
    out = mlp.Regressor(params)(np.array([np.nan, 0.0, 0.0, 0.0, 0.0]))
    assert not np.isfinite(out).all()


def test_inputs_are_clipped_into_the_widened_training_box_when_a_margin_is_set():
    x, y = _data()
    x[:, 2] = 7.0  # constant in the data: the network never saw this column move
    boxed = mlp.train_regressor(x, y, MLPConfig(num_steps=200, input_margin=0.1), seed=0)
    free = mlp.train_regressor(x, y, MLPConfig(num_steps=200), seed=0)
    assert free.input_low is None and free.input_high is None
    span = x.max(axis=0) - x.min(axis=0)
    np.testing.assert_allclose(boxed.input_low, x.min(axis=0) - 0.1 * span)
    np.testing.assert_allclose(boxed.input_high, x.max(axis=0) + 0.1 * span)

    drifted = x[:3].copy()
    drifted[:, 2] += 0.5  # far outside: clipped back to the constant
    np.testing.assert_array_equal(mlp.Regressor(boxed)(drifted), mlp.Regressor(boxed)(x[:3]))
    assert not np.allclose(mlp.Regressor(free)(drifted), mlp.Regressor(free)(x[:3]))
    inside = x[:3].copy()
    inside[:, 0] = x[:, 0].max() + 0.05 * span[0]  # within the margin: seen as is
    np.testing.assert_allclose(mlp.Regressor(boxed)(inside), mlp.Regressor(free)(inside))

    ref = mlp.torch_reference(boxed, drifted) * boxed.output_std + boxed.output_mean
    np.testing.assert_allclose(mlp.Regressor(boxed)(drifted), ref, atol=1e-6)
    back = mlp.MLPParams.from_arrays(boxed.to_arrays("p/"), "p/")
    assert back.identical(boxed)
    with pytest.raises(ValueError, match="input_margin"):
        MLPConfig(input_margin=-0.1)
