"""DD-PPO PointNav policy with habitat-baselines' ``PointNavResNetPolicy`` state_dict layout.

Depth (224x224x1 in [0, 1]) -> 2x2 average pool -> GroupNorm ResNet18 (32 base planes, 16 groups)
-> 3x3 compression conv to round(2048 / (h*w)) channels -> Linear(2048, 512); concatenated with a
32-d embedding of the goal [rho, cos(-theta), sin(-theta)] and a 32-d embedding of the previous action
(in that order: visual, goal, action), fed to a 2-layer LSTM(512); linear actor (4 logits) and critic.

Module names reproduce habitat's keys (``net.tgt_embeding`` is habitat's spelling), so public
checkpoints such as VLFM's ``pointnav_weights.pth`` load unchanged.

Recurrent state is (N, 2 * num_layers, hidden) with the LSTM's h for all layers first and c after
(habitat's ``LSTMStateEncoder`` concatenates (h, c) along the layer axis and permutes to batch-first).

Actions: 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from navbench.policy.resnet import GroupNorm, GroupNormResNet, RunningMeanAndVar

POINTNAV_ACTIONS = ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT")


@dataclass(frozen=True)
class PolicyNetConfig:
    """Architecture; the defaults are the habitat/VLFM depth-only PointNav policy (8.5M parameters)."""

    input_size: tuple[int, int] = (224, 224)  # (H, W) the network expects, before its 2x2 pooling
    hidden_size: int = 512
    num_layers: int = 2  # LSTM layers; the recurrent state has 2 * num_layers rows (h then c)
    base_planes: int = 32
    ngroups: int = 16  # habitat uses base_planes // 2
    num_actions: int = 4
    # habitat turns the running normaliser on only when RGB is observed; depth-only nets go without.
    normalize_visual_inputs: bool = False


class ResNetEncoder(nn.Module):
    """Depth (N, 1, H, W) -> (N, C, h, w) compressed feature map with C*h*w close to 2048."""

    def __init__(self, cfg: PolicyNetConfig) -> None:
        super().__init__()
        # An empty Sequential is an identity with no state_dict keys, which is how habitat spells "off".
        self.running_mean_and_var: nn.Module = RunningMeanAndVar(1) if cfg.normalize_visual_inputs else nn.Sequential()
        self.backbone = GroupNormResNet(1, cfg.base_planes, cfg.ngroups)
        # habitat sizes the compression from the pooled input (H // 2) times the backbone's 1/32.
        h = int(np.ceil((cfg.input_size[0] // 2) * self.backbone.final_spatial_compress))
        w = int(np.ceil((cfg.input_size[1] // 2) * self.backbone.final_spatial_compress))
        channels = int(round(2048 / (h * w)))
        self.compression = nn.Sequential(
            nn.Conv2d(self.backbone.final_channels, channels, kernel_size=3, padding=1, bias=False),
            GroupNorm(1, channels),
            nn.ReLU(True),
        )
        self.output_shape = (channels, h, w)

    def forward(self, depth: torch.Tensor) -> torch.Tensor:
        x = F.avg_pool2d(depth, 2)
        x = self.running_mean_and_var(x)
        return self.compression(self.backbone(x))


class LSTMStateEncoder(nn.Module):
    """LSTM over (T, N, F) inputs whose state is reset wherever ``masks`` is False.

    The sequence is cut at every step where any environment resets; each piece runs as one LSTM
    call, with the state of the resetting environments zeroed at the cut. This is the same result
    as stepping one at a time and much faster for training on rollouts with few resets.
    """

    def __init__(self, input_size: int, hidden_size: int, num_layers: int) -> None:
        super().__init__()
        self.rnn = nn.LSTM(input_size=input_size, hidden_size=hidden_size, num_layers=num_layers)
        self.num_layers = num_layers
        for name, param in self.rnn.named_parameters():
            if "weight" in name:
                nn.init.orthogonal_(param)
            else:
                nn.init.zeros_(param)

    def forward(
        self, x: torch.Tensor, hidden: torch.Tensor, masks: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """x (T, N, F), hidden (N, 2L, H), masks (T, N) bool -> out (T, N, H), hidden (N, 2L, H)."""
        state = hidden.transpose(0, 1)  # (2L, N, H)
        steps = x.shape[0]
        cuts = ((~masks[1:]).any(dim=1).nonzero().flatten() + 1).tolist() if steps > 1 else []
        bounds = [0, *cuts, steps]
        outs = []
        # One step at a time (acting), the cell's arithmetic in plain matrix products (_step): oneDNN's LSTM
        # kernel is several times slower than these for a single step (outputs agree to ~1e-7).
        # Sequences (training) keep nn.LSTM: oneDNN is faster there, especially under bf16 autocast.
        single = steps == 1 and not torch.is_autocast_enabled("cpu")
        for start, end in zip(bounds[:-1], bounds[1:]):
            state = torch.where(masks[start].view(1, -1, 1), state, state.new_zeros(()))
            h, c = state.chunk(2, dim=0)
            if single:
                out, (h, c) = self._step(x[0], h, c)
            else:
                out, (h, c) = self.rnn(x[start:end], (h.contiguous(), c.contiguous()))
            outs.append(out)
            state = torch.cat([h, c], dim=0)
        out = outs[0] if len(outs) == 1 else torch.cat(outs, dim=0)
        return out, state.transpose(0, 1)

    def _step(self, x: torch.Tensor, h: torch.Tensor, c: torch.Tensor
              ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """One step of ``self.rnn``: x (N, F), h and c (L, N, H) -> out (1, N, H), (h, c) as nn.LSTM returns."""
        hs, cs = [], []
        for k in range(self.num_layers):
            w_ih, w_hh = getattr(self.rnn, f"weight_ih_l{k}"), getattr(self.rnn, f"weight_hh_l{k}")
            bias = getattr(self.rnn, f"bias_ih_l{k}") + getattr(self.rnn, f"bias_hh_l{k}")
            gates = torch.addmm(bias, x, w_ih.t()).addmm_(h[k], w_hh.t())
            i, f, g, o = gates.chunk(4, dim=1)  # PyTorch's gate order
            c_k = torch.sigmoid(f) * c[k] + torch.sigmoid(i) * torch.tanh(g)
            x = torch.sigmoid(o) * torch.tanh(c_k)
            hs.append(x)
            cs.append(c_k)
        return x[None], (torch.stack(hs), torch.stack(cs))


class PointNavNet(nn.Module):
    """The ``net.*`` part of habitat's policy: encoders, embeddings and the recurrent core."""

    def __init__(self, cfg: PolicyNetConfig) -> None:
        super().__init__()
        # Index 0 is the "start" token used after a reset; action a is stored at a + 1.
        # Initialised by hand: Embedding's own init on the meta device (load_checkpoint builds there) goes
        # through torch's Python reference ops, which import torch._dynamo (seconds at start-up).
        weight = torch.empty(cfg.num_actions + 1, 32)
        if weight.device.type != "meta":
            nn.init.normal_(weight)
        self.prev_action_embedding = nn.Embedding(cfg.num_actions + 1, 32, _weight=weight)
        self.tgt_embeding = nn.Linear(3, 32)  # sic: habitat's attribute name
        self.visual_encoder = ResNetEncoder(cfg)
        self.visual_fc = nn.Sequential(
            nn.Flatten(), nn.Linear(int(np.prod(self.visual_encoder.output_shape)), cfg.hidden_size), nn.ReLU(True)
        )
        self.state_encoder = LSTMStateEncoder(cfg.hidden_size + 64, cfg.hidden_size, cfg.num_layers)

    def forward(
        self,
        depth: torch.Tensor,
        pointgoal: torch.Tensor,
        prev_actions: torch.Tensor,
        masks: torch.Tensor,
        hidden: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """depth (T, N, H, W, 1), pointgoal (T, N, 2), prev_actions (T, N), masks (T, N) bool."""
        steps, n = masks.shape
        visual = self.encode_depth(depth.reshape(steps * n, *depth.shape[2:]))
        return self.core(visual.view(steps, n, -1), pointgoal, prev_actions, masks, hidden)

    def encode_depth(self, depth: torch.Tensor) -> torch.Tensor:
        """(B, H, W, 1) depth -> (B, C*h*w) flattened visual encoder output (before ``visual_fc``)."""
        # (B, H, W, 1) -> (B, 1, H, W) with NCHW strides. A permute gives the same memory but NHWC strides,
        # and avg_pool2d then takes its channels_last kernel, much slower for one channel (the result is
        # bit-identical). squeeze(-1), not [..., 0]: a frame with more than one channel must still fail
        # here rather than lose its other channels.
        return self.visual_encoder(depth.squeeze(-1).unsqueeze(1)).flatten(1)

    def core(self, visual: torch.Tensor, pointgoal: torch.Tensor, prev_actions: torch.Tensor,
             masks: torch.Tensor, hidden: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Everything after the visual encoder: visual (T, N, C*h*w) -> (features (T, N, H), hidden)."""
        steps, n = masks.shape
        visual = self.visual_fc(visual.reshape(steps * n, -1))
        goal = pointgoal.reshape(steps * n, 2).float()
        rho, theta = goal[:, 0], goal[:, 1]
        goal_emb = self.tgt_embeding(torch.stack([rho, torch.cos(-theta), torch.sin(-theta)], dim=-1))
        flat_masks = masks.reshape(-1)
        action_idx = torch.where(flat_masks, prev_actions.reshape(-1).long() + 1, 0)
        action_emb = self.prev_action_embedding(action_idx)
        x = torch.cat([visual, goal_emb.to(visual.dtype), action_emb.to(visual.dtype)], dim=1)
        return self.state_encoder(x.view(steps, n, -1), hidden, masks)


class CategoricalHead(nn.Module):
    """Actor: ``action_distribution.linear`` producing logits (habitat's CategoricalNet)."""

    def __init__(self, num_inputs: int, num_outputs: int) -> None:
        super().__init__()
        self.linear = nn.Linear(num_inputs, num_outputs)
        nn.init.orthogonal_(self.linear.weight, gain=0.01)
        nn.init.zeros_(self.linear.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.linear(x)


class CriticHead(nn.Module):
    """Critic: ``critic.fc`` producing the state value."""

    def __init__(self, num_inputs: int) -> None:
        super().__init__()
        self.fc = nn.Linear(num_inputs, 1)
        nn.init.orthogonal_(self.fc.weight)
        nn.init.zeros_(self.fc.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(x)


class PointNavResNetPolicy(nn.Module):
    """Actor-critic with habitat-baselines' ``PointNavResNetPolicy`` parameter names.

    ``forward`` runs either one step (inputs (N, ...)) or a sequence for truncated BPTT (inputs
    (T, N, ...)), told apart by the rank of ``depth``:

    - depth (N, H, W, 1) or (T, N, H, W, 1), float in [0, 1], H, W = ``cfg.input_size``;
    - pointgoal (N, 2) / (T, N, 2): [rho (m), theta (rad, counter-clockwise positive)];
    - prev_actions (N,) / (T, N) (a trailing singleton axis is accepted): the action taken before
      this step; ignored where the mask is False;
    - masks (N,) / (T, N), bool or 0/1: False on an episode's first step, which zeroes the recurrent
      state before that step and feeds the "start" action token;
    - hidden (N, 2 * num_layers, hidden_size): the state before the first step.

    Returns logits (N, A) / (T, N, A), value (N,) / (T, N), and the state after the last step.
    """

    def __init__(self, cfg: PolicyNetConfig = PolicyNetConfig()) -> None:
        super().__init__()
        self.cfg = cfg
        self.net = PointNavNet(cfg)
        self.action_distribution = CategoricalHead(cfg.hidden_size, cfg.num_actions)
        self.critic = CriticHead(cfg.hidden_size)

    def forward_features(self, visual: torch.Tensor, pointgoal: torch.Tensor, prev_actions: torch.Tensor,
                         masks: torch.Tensor, hidden: torch.Tensor
                         ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Sequence mode from precomputed ``net.encode_depth`` outputs (T, N, C*h*w): training with a
        frozen visual encoder caches those once instead of running the ResNet every epoch."""
        features, hidden = self.net.core(visual, pointgoal.reshape(*masks.shape, 2), prev_actions.reshape(masks.shape),
                                         masks.reshape(masks.shape) != 0, hidden)
        logits, value = _heads(self, features)
        return logits, value, hidden

    @property
    def num_recurrent_layers(self) -> int:
        return 2 * self.cfg.num_layers

    def initial_hidden(self, n: int, device: torch.device | str = "cpu") -> torch.Tensor:
        return torch.zeros(n, self.num_recurrent_layers, self.cfg.hidden_size, device=device)

    def forward(
        self,
        depth: torch.Tensor,
        pointgoal: torch.Tensor,
        prev_actions: torch.Tensor,
        masks: torch.Tensor,
        hidden: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        sequence = depth.dim() == 5
        if not sequence and depth.dim() != 4:
            raise ValueError(f"depth must be (N, H, W, 1) or (T, N, H, W, 1), got shape {tuple(depth.shape)}")
        if tuple(depth.shape[-3:]) != (*self.cfg.input_size, 1):
            raise ValueError(
                f"depth must be {self.cfg.input_size[0]}x{self.cfg.input_size[1]}x1, got shape {tuple(depth.shape)}"
                " (resize with navbench.policy.prepare_depth)"
            )
        lead = depth.shape[:2] if sequence else (1, depth.shape[0])
        masks = masks.reshape(lead) != 0
        prev_actions = prev_actions.reshape(lead)
        pointgoal = pointgoal.reshape(*lead, 2)
        depth = depth.to(torch.float32)
        if not sequence:
            depth = depth.unsqueeze(0)
        features, hidden = self.net(depth, pointgoal, prev_actions, masks, hidden)
        logits, value = _heads(self, features)
        if not sequence:
            logits, value = logits[0], value[0]
        return logits, value, hidden


def _heads(policy: PointNavResNetPolicy, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    return policy.action_distribution(features), policy.critic(features).squeeze(-1)


def prepare_depth(depth: np.ndarray | torch.Tensor, size: tuple[int, int] = (224, 224)) -> torch.Tensor:
    """Depth (N, H, W, 1), (N, H, W) or (H, W), float in [0, 1] -> float32 tensor (N, *size, 1).

    Resizes with area averaging (``F.interpolate(mode="area")``), as VLFM does with cv2's INTER_AREA,
    so a downscaled depth keeps mean depth per pixel rather than aliasing thin obstacles away.
    """
    t = torch.as_tensor(depth, dtype=torch.float32)
    if t.dim() == 2:
        t = t[None, :, :, None]
    elif t.dim() == 3:
        t = t[..., None]
    if t.dim() != 4 or t.shape[-1] != 1:
        raise ValueError(f"depth must be (N, H, W, 1), (N, H, W) or (H, W), got shape {tuple(t.shape)}")
    if tuple(t.shape[1:3]) != tuple(size):
        t = F.interpolate(t.permute(0, 3, 1, 2), size=tuple(size), mode="area").permute(0, 2, 3, 1)
    return t


DECODINGS = ("argmax", "sample", "least-tried")


@dataclass(frozen=True)
class InferenceConfig:
    """Options of :class:`PointNavAgentPolicy`.

    Defaults are fp32 with channels_last: NHWC lets oneDNN pick faster convolution kernels, with logits
    equal to ~1e-6. bf16 is off: without AVX512-BF16/AMX it is emulated and slow, and it changes some
    argmax decisions. ``benchmarks/policy_speed.py --all`` measures every combination.
    """

    reset_goal_dist: float = 0.1  # m; a goal that moves farther than this restarts the recurrent state
    bf16: bool = False  # torch.autocast(cpu, bfloat16) around the forward pass
    channels_last: bool = True  # NHWC memory layout for the convolutions (converts the policy in place)
    # How actions are chosen from the logits (one of DECODINGS):
    # - "argmax": the most probable action;
    # - "sample": every action drawn from softmax(logits / temperature), as habitat-baselines' evaluator
    #   does (``actor_critic.act(..., deterministic=False)``);
    # - "least-tried": the argmax, except at a pose the episode has already been in (the same goal vector,
    #   to 2 cm and 2 degrees, since the last reset), where the action is drawn among the movements taken
    #   there least often (STOP keeps its own probability). Back at a pose, the argmax tends to repeat
    #   what brought it there (FORWARD into an obstacle beside the view, turning on the spot in a corner).
    # Draws are reproducible through ``reset(i, seed=)``: each env draws from its own generator, so
    # batching changes no action.
    decoding: str = "argmax"
    # With "sample": 1 is the policy's own distribution; lower values move the draws towards the argmax.
    temperature: float = 1.0

    def __post_init__(self) -> None:
        if self.decoding not in DECODINGS:
            raise ValueError(f"unknown decoding {self.decoding!r}: choose from {', '.join(DECODINGS)}")
        if not self.temperature > 0:  # also refuses NaN
            raise ValueError(f"temperature must be > 0, got {self.temperature}")
        if self.temperature != 1.0 and self.decoding != "sample":
            raise ValueError(f"temperature applies to decoding 'sample' only, not {self.decoding!r}")


class PointNavAgentPolicy:
    """Stateful, batched inference around :class:`PointNavResNetPolicy`: actions decoded as
    ``config.decoding`` says, any draws from each env's seeded generator.

    Keeps per environment the recurrent state, the previous action, whether the next step starts an
    episode, and the last goal position in world coordinates (when the caller provides it).

    ``frozen=True`` (an evaluation: the weights never change) reuses the visual encoding of one of the last
    ``FRAMES_KEPT`` calls when the same envs hand in the same frames again (an agent pressed against a wall,
    its FORWARD refused, or turning back and forth on the spot sees the same depth again); the encoder is
    deterministic, so the actions are those of encoding the frames again.
    """

    FRAMES_KEPT = 16

    def __init__(
        self, policy: PointNavResNetPolicy, num_envs: int = 1, config: InferenceConfig = InferenceConfig(),
        device: torch.device | str | None = None, frozen: bool = False,
    ) -> None:
        self.config = config
        self.num_envs = num_envs
        self.frozen = frozen
        # (envs, hash of the input) -> (input, its encoding), the last FRAMES_KEPT calls' (frozen only)
        self._encoded: OrderedDict[tuple, tuple[torch.Tensor, torch.Tensor]] = OrderedDict()
        # the network and its recurrent state live on `device` (None: where the policy's weights are, as a
        # trainer's shared learner); decoding and its draws stay on the CPU
        self.device = torch.device(device) if device is not None else next(policy.parameters()).device
        self.policy = policy.eval().to(self.device)
        if config.channels_last:
            self.policy = self.policy.to(memory_format=torch.channels_last)
        self.hidden = self.policy.initial_hidden(num_envs, self.device)
        self.prev_actions = torch.zeros(num_envs, dtype=torch.long, device=self.device)
        self.masks = torch.zeros(num_envs, dtype=torch.bool, device=self.device)
        self.goal_world = np.full((num_envs, 3), np.nan)
        # until reset(i, seed=) each env draws from its own stream, so no two envs repeat each other's draws
        self.rngs = [np.random.default_rng([0, k]) for k in range(num_envs)]
        # per env: goal vector key -> how often each action was taken at that pose since the last reset
        self.visited: list[dict[tuple[int, int], np.ndarray]] = [{} for _ in range(num_envs)]

    def _envs(self, i: int | None) -> slice | list[int]:
        return slice(None) if i is None else [i]

    def reset(self, i: int | None = None, seed: int | list[int] | None = None) -> None:
        """Start a new episode in env ``i`` (all envs when None): clears state, action and goal; with
        ``seed``, also restarts the generator this env's actions are drawn from."""
        self.reset_hidden(i)
        self.goal_world[self._envs(i)] = np.nan
        if seed is not None:
            for k in range(self.num_envs) if i is None else [i]:
                self.rngs[k] = np.random.default_rng(seed)

    def reset_hidden(self, i: int | None = None) -> None:
        """Restart the recurrent state of env ``i`` (all when None); the next step uses the start token."""
        idx = self._envs(i)
        self.hidden[idx] = 0.0
        self.prev_actions[idx] = 0
        self.masks[idx] = False
        for k in range(self.num_envs) if i is None else [i]:
            self.visited[k].clear()

    def _track_goals(self, goal_world: np.ndarray) -> None:
        goal = np.asarray(goal_world, dtype=np.float64).reshape(self.num_envs, -1)
        if goal.shape[1] not in (2, 3):
            raise ValueError(f"goal_world must be (N, 2) or (N, 3), got shape {np.shape(goal_world)}")
        goal = np.pad(goal, ((0, 0), (0, 3 - goal.shape[1])))
        known = ~np.isnan(self.goal_world[:, 0])
        moved = known & (np.linalg.norm(goal - np.nan_to_num(self.goal_world), axis=1) > self.config.reset_goal_dist)
        for i in np.flatnonzero(moved):
            self.reset_hidden(int(i))
        # As VLFM does, remember the latest goal even after a small move, so slow drift never resets.
        self.goal_world = goal

    def _taken_here(self, pointgoal: np.ndarray, envs: list[int]) -> list[np.ndarray]:
        """Per env of ``envs``: how often each action was taken at this goal vector (rho to 2 cm, theta to 2
        degrees) since the reset; all zeros at a new pose. The caller counts the action it takes. A refused
        FORWARD or a turn back and forth repeats the pose and so the vector."""
        return [self.visited[k].setdefault((int(round(rho / 0.02)), int(round(np.degrees(theta) / 2.0)) % 180),
                                           np.zeros(4, np.int64))
                for k, (rho, theta) in zip(envs, pointgoal.astype(np.float64))]

    def act(
        self,
        depth: np.ndarray | torch.Tensor,
        pointgoal: np.ndarray | torch.Tensor,
        goal_world: np.ndarray | None = None,
        rows: list[int] | None = None,
    ) -> np.ndarray:
        """depth (N, H, W, 1) in [0, 1], pointgoal (N, 2) [rho, theta] -> actions (N,) int64.

        Depth of another size is area-resized to the network's input. With ``goal_world`` (N, 3)
        (or (N, 2)), an env whose goal moved more than ``reset_goal_dist`` since the last call
        restarts its recurrent state first. With ``rows``, steps only those envs (N = len(rows)),
        leaving the others' state as it was: a batch of the envs that want an action this step.
        """
        return self.act_and_encode(depth, pointgoal, goal_world, rows)[0]

    def act_and_encode(
        self,
        depth: np.ndarray | torch.Tensor,
        pointgoal: np.ndarray | torch.Tensor,
        goal_world: np.ndarray | None = None,
        rows: list[int] | None = None,
    ) -> tuple[np.ndarray, torch.Tensor]:
        """:meth:`act`, also returning the visual encoder's output (N, C*h*w) for these frames: DAgger
        collection with a frozen encoder stores it rather than encoding every frame a second time."""
        if goal_world is not None:
            if rows is not None:
                raise ValueError("goal_world tracks every env's goal: step all envs (rows=None) with it")
            self._track_goals(goal_world)
        envs = list(range(self.num_envs)) if rows is None else [int(k) for k in rows]
        idx = slice(None) if rows is None else envs
        x = prepare_depth(depth, self.policy.cfg.input_size)
        goal = torch.as_tensor(pointgoal, dtype=torch.float32).reshape(-1, 2)
        if x.shape[0] != len(envs) or goal.shape[0] != len(envs):
            raise ValueError(
                f"expected a batch of {len(envs)}, got depth {tuple(x.shape)} and pointgoal {tuple(goal.shape)}"
            )
        dev = self.device
        with torch.inference_mode(), torch.autocast(dev.type, dtype=torch.bfloat16, enabled=self.config.bf16):
            # The two halves of PointNavResNetPolicy.forward, so the encoder output can be handed out.
            visual = self._encode(x, envs)
            logits, _, hidden = self.policy.forward_features(visual[None], goal.to(dev)[None],
                                                             self.prev_actions[idx][None], self.masks[idx][None],
                                                             self.hidden[idx])
        # Outside inference_mode these ops give normal tensors, which reset_hidden may edit in place.
        actions = self._decode(logits[0].cpu(), goal, envs)
        visual = visual.cpu()
        if dev.type != "cpu":
            actions = actions.to(dev)
        if rows is None:
            self.hidden = hidden.float().clone()
            self.prev_actions = actions.clone()
        else:
            self.hidden[idx] = hidden.float()
            self.prev_actions[idx] = actions
        self.masks[idx] = True
        return actions.cpu().numpy().astype(np.int64), visual.float()  # an inference tensor: read it, or copy it

    def _encode(self, x: torch.Tensor, envs: list[int]) -> torch.Tensor:
        """The visual encoding of the frames ``x`` of ``envs``, reused when a frozen policy encoded them lately."""
        if not self.frozen:
            return self.policy.net.encode_depth(x.to(self.device))
        frames = x.contiguous()
        key = (tuple(envs), hash(frames.numpy().tobytes()))
        kept = self._encoded.get(key)
        if kept is not None and torch.equal(kept[0], frames):
            self._encoded.move_to_end(key)
            return kept[1]
        visual = self.policy.net.encode_depth(x.to(self.device))
        self._encoded[key] = (frames.clone(), visual)  # x may share the caller's array
        if len(self._encoded) > self.FRAMES_KEPT:
            self._encoded.popitem(last=False)
        return visual

    def _decode(self, logits: torch.Tensor, goal: torch.Tensor, envs: list[int]) -> torch.Tensor:
        """Actions (len(envs),) from the logits (len(envs), A) of ``envs`` as ``config.decoding`` says."""
        decoding = self.config.decoding
        argmax = logits.float().argmax(dim=-1)
        if decoding == "argmax":
            return argmax
        # inverse CDF with one uniform draw per env and step (drawn whether or not it is used): the same
        # draws give the same actions at any batch size
        probs = torch.softmax(logits.double() / self.config.temperature, dim=-1).numpy()
        u = np.array([self.rngs[k].random() for k in envs])
        if decoding == "sample":
            return torch.as_tensor(self._pick(probs, u), dtype=torch.long)
        taken = self._taken_here(goal.numpy(), envs)
        seen = np.array([t.any() for t in taken])
        for k in np.flatnonzero(seen):
            p = probs[k].copy()
            moves = taken[k][1:]
            p[1:][moves > moves.min()] = 0.0
            # the movements left take the mass of those masked; STOP keeps its own probability
            # (renormalised, a near-zero STOP far from the goal would be drawn often)
            if p[1:].sum() > 0:
                p[1:] *= (1.0 - p[0]) / p[1:].sum()
                probs[k] = p
        picks = np.where(seen, self._pick(probs, u), argmax.numpy())
        for k in range(len(envs)):
            taken[k][int(picks[k])] += 1
        return torch.as_tensor(picks, dtype=torch.long)

    @staticmethod
    def _pick(probs: np.ndarray, u: np.ndarray) -> np.ndarray:
        return (probs.cumsum(-1) < u[:, None]).sum(-1).clip(max=probs.shape[-1] - 1)
