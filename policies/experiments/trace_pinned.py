"""Replay a PointNav run's pinned failures and compare the policy with the geodesic expert step by step.

    PYOPENGL_PLATFORM=osmesa python policies/experiments/trace_pinned.py policies/pointnav_navbench.pth \
        results/runs/pointnav_val/episodes.jsonl

"Pinned" is the model card's definition: a timeout with > 50 blocked FORWARDs or < 5 m covered. For each
such episode of the records (PointNav val), the checkpoint drives it again at batch 1 (argmax) while the
training expert (``GreedyFollower``, 0.1 m STOP, 0.15 m clearance) labels every state. Printed per
episode: blocked FORWARDs, the policy's mean P(FORWARD) on the step right after one, its agreement with
the expert (all steps / steps after a blocked FORWARD), the shortest period the last 36 actions repeat
with (0: none up to 8), how often the optimistic follower (shortest path over what the frames have
shown, unseen cells free), fed the same frames, takes the expert's and the policy's action, and the
last 40 actions of all three (S F L R).
"""

import json
import sys

import numpy as np
import torch

from navbench.env.config import EnvConfig
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.io import load_dataset
from navbench.paths import split_file
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import PointNavAgentPolicy, prepare_depth
from navbench.scene.follower import GreedyFollower
from navbench.scene.optimistic import OptimisticFollower


def period(actions: list[int], window: int = 36, longest: int = 8) -> int:
    tail = actions[-window:]
    for p in range(1, longest + 1):
        if len(tail) == window and all(tail[i] == tail[i - p] for i in range(p, window)):
            return p
    return 0


def main(checkpoint: str, records: str) -> None:
    recs = [json.loads(line) for line in open(records)]
    pinned = [r for r in recs if not r["success"] and not r["stop_called"]
              and (r["collisions"] > 50 or r["path_length"] < 5)]
    env = PointNavEnv(load_dataset(split_file("pointnav", "val")), config=EnvConfig(rgb=False, depth=True))
    policy = PointNavAgentPolicy(load_checkpoint(checkpoint), 1)
    for r in pinned:
        obs, _ = env.reset(options={"episode": r["episode_id"]})
        policy.reset(0)
        expert = GreedyFollower(env.navgrid, env.goal_points, 0.1, clearance_margin=0.15)
        c = env.config
        optimist = OptimisticFollower(env.navgrid, env.goal_points, 0.1, c.hfov_deg, c.min_depth, c.max_depth)
        blocked, collisions = False, 0
        p_forward, taken, labels, after_block, optimistic = [], [], [], [], []
        for _ in range(500):
            with torch.inference_mode():
                visual = policy.policy.net.encode_depth(prepare_depth(obs["depth"][None]))
                goal = torch.as_tensor(obs["pointgoal_with_gps_compass"][None])
                logits, _, hidden = policy.policy.forward_features(visual[None], goal[None], policy.prev_actions[None],
                                                                   policy.masks[None], policy.hidden)
            probs = torch.softmax(logits[0, 0].float(), -1).numpy()
            action = int(probs.argmax())
            labels.append(int(expert.next_action(env.agent_position, env.agent_rotation)))
            optimist.observe(obs["depth"], env.agent_position, env.agent_yaw)
            optimistic.append(int(optimist.next_action(env.agent_position, env.agent_rotation)))
            taken.append(action)
            after_block.append(blocked)
            if blocked:
                p_forward.append(float(probs[1]))
            policy.hidden, policy.prev_actions = hidden.float().clone(), torch.tensor([action])
            policy.masks[:] = True
            obs, _, term, trunc, info = env.step(action)
            blocked, collisions = action == 1 and info["collisions"] > collisions, info["collisions"]
            if term or trunc:
                break
        a, e, b, o = np.array(taken), np.array(labels), np.array(after_block), np.array(optimistic)
        print(f"episode {r['episode_id']}: blocked {int(b.sum())}, P(F) after a block {np.mean(p_forward):.2f}, "
              f"agrees {np.mean(a == e):.2f} / {np.mean(a[b] == e[b]) if b.any() else float('nan'):.2f}, "
              f"period {period(taken)}, success {info['success']:.0f}; optimistic follower agrees with the expert "
              f"{np.mean(o == e):.2f}, with the policy {np.mean(o == a):.2f}")
        print("  policy " + "".join("SFLR"[i] for i in taken[-40:]) + "\n  expert " + "".join("SFLR"[i] for i in labels[-40:])
              + "\n  optim. " + "".join("SFLR"[i] for i in optimistic[-40:]))


if __name__ == "__main__":
    main(*sys.argv[1:3])
