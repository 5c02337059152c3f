"""The image encoder E: VGG-19 weight files load; the default autoencoder trains, saves and loads."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from actaim2.data.encoder import AUTOENCODER_SPEC, ImageEncoder
from actaim2.data.encoder_training import train_autoencoder
from actaim2.data.vgg import load_vgg19_features, vgg19_features

# torchvision.models.vgg19().features: the Conv2d indices of configuration "E".
TORCHVISION_CONV_INDICES = [0, 2, 5, 7, 10, 12, 14, 16, 19, 21, 23, 25, 28, 30, 32, 34]


def test_vgg19_layout_matches_torchvision():
    features = vgg19_features()
    assert len(features) == 37
    assert list(features.state_dict()) == [f"{i}.{p}" for i in TORCHVISION_CONV_INDICES for p in ("weight", "bias")]
    assert features[34].weight.shape == (512, 512, 3, 3) and features[0].weight.shape == (64, 3, 3, 3)
    assert isinstance(features[36], torch.nn.MaxPool2d)


def test_vgg19_weight_file_loads(tmp_path):
    torch.manual_seed(0)
    reference = vgg19_features()
    full = {f"features.{k}": v for k, v in reference.state_dict().items()}  # a torchvision vgg19 state_dict ...
    full.update({"classifier.0.weight": torch.zeros(4096, 25088), "classifier.0.bias": torch.zeros(4096)})  # ... with its head
    torch.save(full, tmp_path / "vgg19.pth")
    torch.save(reference.state_dict(), tmp_path / "vgg19_features.pth")
    x = torch.rand(1, 3, 64, 64)
    for name in ("vgg19.pth", "vgg19_features.pth"):
        loaded = load_vgg19_features(tmp_path / name)
        torch.testing.assert_close(loaded(x), reference(x))
    encoder = ImageEncoder.vgg19(tmp_path / "vgg19.pth")
    assert encoder(torch.rand(2, 3, 64, 64)).shape == (2, 512 * 7 * 7)


def test_wrong_weight_file_is_refused(tmp_path):
    bn = {"features.0.weight": torch.zeros(64, 3, 3, 3), "features.1.running_mean": torch.zeros(64)}  # vgg19_bn-like
    torch.save(bn, tmp_path / "bn.pth")
    with pytest.raises(ValueError, match="not a VGG-19 features state_dict"):
        load_vgg19_features(tmp_path / "bn.pth")


def test_autoencoder_trains_and_round_trips(tmp_path, make_trajectory):
    traj = make_trajectory(moved=0.5)
    prep = ImageEncoder(AUTOENCODER_SPEC, torch.nn.Identity())
    obs = [traj.observations["init"], traj.observations["final"]]
    data = torch.cat([prep.preprocess([o[c] for c in sorted(o)]) for o in obs])
    encoder, losses = train_autoencoder(data, steps=60, batch_size=8, seed=0)
    assert np.mean(losses[-10:]) < 0.5 * np.mean(losses[:5])
    z = encoder.encode(obs)
    assert z.shape == (2, 5 * encoder.dim_per_camera)
    assert np.linalg.norm(z[0] - z[1]) > 0  # the moved box changes E
    encoder.save(tmp_path / "encoder.pt")
    np.testing.assert_allclose(ImageEncoder.load(tmp_path / "encoder.pt").encode(obs), z, rtol=1e-5, atol=1e-6)
