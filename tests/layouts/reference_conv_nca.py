"""A plain reference for the batched conv NCA: the original's network as a torch ``nn.Sequential``, its weights set
from the flat vector parameter by parameter in ``state_dict`` order, run one genome at a time."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn


def reference_grow(genome: np.ndarray, seed: np.ndarray, iterations: int, tiles: int, hidden: int = 32) -> np.ndarray:
    network = nn.Sequential(
        nn.Conv2d(tiles, hidden, 3, 1, 1),
        nn.ReLU(),
        nn.Conv2d(hidden, hidden, 1),
        nn.ReLU(),
        nn.Conv2d(hidden, tiles, 1),
        nn.Sigmoid(),
    )
    state, start = network.state_dict(), 0
    for name, tensor in state.items():
        size = tensor.numel()
        state[name] = torch.tensor(genome[start : start + size], dtype=torch.float32).reshape(tensor.shape)
        start += size
    assert start == len(genome)
    network.load_state_dict(state)
    x = torch.eye(tiles)[torch.as_tensor(seed).long()][None].permute(0, 3, 1, 2)
    with torch.no_grad():
        for _ in range(iterations):
            x = network(x)
    return x.argmax(1)[0].numpy().astype(np.uint8)
