"""GroupNorm ResNet backbone and running input normaliser, laid out like habitat-baselines' DD-PPO.

The module tree (attribute names and ``nn.Sequential`` indices) is what fixes the state_dict keys,
so it follows habitat-baselines' ``rl/ddppo/policy/resnet.py`` exactly:

- ``conv1``: Sequential(Conv 7x7 stride 2, GroupNorm, ReLU), then ``maxpool`` 3x3 stride 2;
- ``layer1..layer4``: Sequential of :class:`BasicBlock`, each holding ``convs`` = Sequential(conv3x3,
  GroupNorm, ReLU, conv3x3, GroupNorm) and, when the shape changes, ``downsample`` =
  Sequential(conv1x1, GroupNorm).

GroupNorm instead of BatchNorm is what DD-PPO trains with (batch statistics are meaningless across
correlated rollout frames), so there is no train/eval difference in the backbone.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class GroupNorm(nn.GroupNorm):
    """``nn.GroupNorm`` (the same parameters and state_dict keys) that normalises in fp32 under autocast.

    Why: given a bfloat16 input and fp32 weights (what autocast hands it), PyTorch runs its mixed-precision
    channels_last kernel, which is slower than the fp32 one, forward and backward, and cancels what bf16
    convolutions save. Normalising in fp32 and handing back the input's dtype keeps those savings.
    When the input has the weights' dtype (fp32 runs, outside autocast) it is exactly ``nn.GroupNorm``.
    """

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.dtype == self.weight.dtype:
            return super().forward(x)
        with torch.autocast(x.device.type, enabled=False):
            y = F.group_norm(x.float(), self.num_groups, self.weight, self.bias, self.eps)
        return y.to(x.dtype)


def _conv3x3(in_planes: int, out_planes: int, stride: int = 1) -> nn.Conv2d:
    return nn.Conv2d(in_planes, out_planes, kernel_size=3, stride=stride, padding=1, bias=False)


def _conv1x1(in_planes: int, out_planes: int, stride: int = 1) -> nn.Conv2d:
    return nn.Conv2d(in_planes, out_planes, kernel_size=1, stride=stride, bias=False)


class BasicBlock(nn.Module):
    """Two 3x3 convolutions with GroupNorm and an identity (or 1x1 projected) shortcut."""

    def __init__(self, inplanes: int, planes: int, ngroups: int, stride: int = 1) -> None:
        super().__init__()
        self.convs = nn.Sequential(
            _conv3x3(inplanes, planes, stride),
            GroupNorm(ngroups, planes),
            nn.ReLU(True),
            _conv3x3(planes, planes),
            GroupNorm(ngroups, planes),
        )
        # habitat stores `downsample = None` when the shortcut is the identity, so no keys appear.
        self.downsample: nn.Module | None = None
        if stride != 1 or inplanes != planes:
            self.downsample = nn.Sequential(_conv1x1(inplanes, planes, stride), GroupNorm(ngroups, planes))
        self.relu = nn.ReLU(True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        residual = x if self.downsample is None else self.downsample(x)
        return self.relu(self.convs(x) + residual)


class GroupNormResNet(nn.Module):
    """ResNet of BasicBlocks; ``layers=(2, 2, 2, 2)`` is habitat's ``resnet18``.

    Output has ``final_channels = base_planes * 8`` channels and 1/32 of the input resolution
    (``final_spatial_compress``), which the encoder uses to size its compression layer.
    """

    final_spatial_compress = 1.0 / 32.0

    def __init__(
        self, in_channels: int, base_planes: int, ngroups: int, layers: tuple[int, int, int, int] = (2, 2, 2, 2)
    ) -> None:
        super().__init__()
        self.conv1 = nn.Sequential(
            nn.Conv2d(in_channels, base_planes, kernel_size=7, stride=2, padding=3, bias=False),
            GroupNorm(ngroups, base_planes),
            nn.ReLU(True),
        )
        self.maxpool = nn.MaxPool2d(kernel_size=3, stride=2, padding=1)
        inplanes = base_planes
        stages = []
        for i, blocks in enumerate(layers):
            planes = base_planes * 2**i
            stride = 1 if i == 0 else 2
            stage = [BasicBlock(inplanes, planes, ngroups, stride)]
            stage += [BasicBlock(planes, planes, ngroups) for _ in range(1, blocks)]
            stages.append(nn.Sequential(*stage))
            inplanes = planes
        self.layer1, self.layer2, self.layer3, self.layer4 = stages
        self.final_channels = inplanes

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.maxpool(self.conv1(x))
        return self.layer4(self.layer3(self.layer2(self.layer1(x))))


class RunningMeanAndVar(nn.Module):
    """Per-channel running input normaliser (habitat's ``RunningMeanAndVar``).

    Buffers ``_mean``/``_var`` of shape (1, C, 1, 1) and a scalar ``_count``. Statistics update only
    in training mode (Chan et al. parallel merge of batch moments); the variance is floored at 1e-2
    before the inverse square root, as habitat does, so a freshly built normaliser scales by 10.
    habitat enables it only when RGB is observed; depth-only checkpoints (VLFM's) do not have it.
    """

    def __init__(self, n_channels: int) -> None:
        super().__init__()
        self.register_buffer("_mean", torch.zeros(1, n_channels, 1, 1))
        self.register_buffer("_var", torch.zeros(1, n_channels, 1, 1))
        self.register_buffer("_count", torch.zeros(()))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.training:
            with torch.no_grad():
                flat = x.detach().transpose(0, 1).reshape(x.shape[1], -1).float()
                new_mean = flat.mean(-1).view(1, -1, 1, 1)
                new_var = flat.var(-1, unbiased=False).view(1, -1, 1, 1)
                new_count = torch.full_like(self._count, x.shape[0])
                total = self._count + new_count
                m2 = (
                    self._var * self._count
                    + new_var * new_count
                    + (new_mean - self._mean).pow(2) * self._count * new_count / total
                )
                self._var.copy_(m2 / total)
                self._mean.copy_((self._count * self._mean + new_count * new_mean) / total)
                self._count.add_(new_count)
        inv_std = torch.rsqrt(self._var.clamp_min(1e-2))
        return torch.addcmul(-self._mean * inv_std, x, inv_std)
