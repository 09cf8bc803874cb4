"""navbench.metrics.goat_metrics against a separate port of goat-bench's measures (tests/goat_reference.py),
on scripted action sequences over a fake simulator."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.metrics import GoatMeasures, goat_metrics

sys.path.insert(0, str(Path(__file__).parent))
import goat_reference as ref  # noqa: E402

F, L, R, UP, DOWN, STOP, SUB = 1, 2, 3, 4, 5, 0, 6


def vp(*points):
    return {"view_points": [{"agent_state": {"position": list(p), "rotation": [0, 0, 0, 1]}} for p in points]}


# start (0, 0, 0) facing -z; goals on the 0.25 m lattice so the oracle lands on view points
TASKS = [["chair", "object", None], ["bed", "description", "bed_5"], ["sofa", "image", "sofa_7", 3],
         ["sofa", "object", None]]
GOALS = [[vp((0, 0, -1.0), (3, 0, 3)), vp((9, 0, 9))],  # object: any instance of the category
         [vp((0.5, 0, -1.0))], [vp((0.5, 0, -2.0))], [vp((1.5, 0, -2.0)), vp((3.0, 0, -4.0))]]
ORACLE = [F, F, F, F, SUB, R, F, F, SUB, L, F, F, F, F, SUB, R, F, F, F, F, SUB]


def run(actions, tasks=TASKS, goals=GOALS, max_steps=5000):
    """The reference's metrics after ``actions``, and the states navbench's env would report."""
    sim = ref.FakeSim([0.0, 0.0, 0.0])
    env = ref.Env(sim, ref.Episode(tasks, goals), max_episode_steps=max_steps)
    env.reset()

    def state(action):
        k = env.task.active_subtask_idx
        pts = [v["agent_state"]["position"] for g in goals[k] for v in g["view_points"]] if k < len(goals) else None
        d = sim.geodesic_distance(sim.position, pts) if pts else float("nan")
        return (action, sim.position.tolist(), d)

    states = [state(None)]
    for a in actions:
        env.step(a)
        states.append(state(a))
        if env.episode_over:
            break
    return env, states


KEYS = ("partial_success", "composite_success", "task_success", "object_success", "description_success",
        "image_success")


def assert_same(env, ours):
    m = env.metrics()
    for k in KEYS:
        assert ours[k] == pytest.approx(float(m["success"][k])), k
    assert ours["subtask_success"] == m["success"]["subtask_success"]
    assert ours["composite_spl"] == pytest.approx(m["spl"]["composite_spl"])
    assert ours["spl_by_subtask"] == pytest.approx([float(v) for v in m["spl"]["spl_by_subtask"]])
    assert ours["composite_softspl"] == pytest.approx(m["soft_spl"]["composite_softspl"])


def types(tasks=TASKS):
    return [t[1] for t in tasks]


def test_oracle_with_subtask_stop_at_each_goal():
    env, states = run(ORACLE)
    assert env.episode_over and len(states) == len(ORACLE) + 1  # the last SUBTASK_STOP ended it
    ours = goat_metrics(types(), states)
    assert_same(env, ours)
    assert ours["partial_success"] == 1.0 and ours["composite_success"] == 1.0 and ours["composite_spl"] == 1.0
    assert ours["task_success"] == 0.0 and ours["task_success_corrected"] == 1.0  # the code's task_success is never 1
    assert ours["d0_by_subtask"] == pytest.approx([1.0, 0.5, 1.0, 1.0])


def test_detours_and_a_miss():
    # subtask 0 by a detour (left, back, on), subtask 1 stopped 0.25 m short, subtask 2 reached, 3 missed
    actions = [L, F, L, L, F, L, F, F, F, F, SUB, R, F, SUB, L, R, F, L, F, F, F, F, SUB, SUB]
    env, states = run(actions)
    ours = goat_metrics(types(), states)
    assert_same(env, ours)
    assert ours["subtask_success"] == [1.0, 0.0, 1.0, 0.0]
    assert 0 < ours["spl_by_subtask"][0] < 1 and 0 < ours["softspl_by_subtask"][1] < 1
    assert ours["object_success"] == 0.5 and ours["description_success"] == 0.0 and ours["image_success"] == 1.0


def test_subtask_stop_at_once():
    env, states = run([SUB] * 4)
    ours = goat_metrics(types(), states)
    assert_same(env, ours)
    assert ours["partial_success"] == 0.0 and ours["composite_spl"] == 0.0 and ours["composite_softspl"] == 0.0
    assert ours["subtasks_closed"] == 4


def test_plain_stop_mid_episode_ends_it_and_the_rest_score_zero():
    actions = [F, F, F, F, SUB, R, F, F, STOP, SUB, SUB]
    env, states = run(actions)
    assert env.episode_over and len(states) == 10  # nothing after STOP is taken
    ours = goat_metrics(types(), states)
    assert_same(env, ours)
    # subtask 1 stood on its goal at STOP and still scores 0: only SUBTASK_STOP closes a subtask
    assert ours["subtask_success"] == [1.0, 0.0, 0.0, 0.0] and ours["partial_success"] == 0.25
    assert ours["stop_called"] and ours["subtasks_closed"] == 1


def test_look_up_down_do_not_move():
    actions = [UP, DOWN, F, F, F, F, SUB] + ORACLE[5:]
    env, states = run(actions)
    ours = goat_metrics(types(), states)
    assert_same(env, ours)
    assert ours["composite_spl"] == 1.0


def test_episode_step_limit():
    env, states = run(ORACLE, max_steps=7)
    assert env.episode_over and len(states) == 8
    ours = goat_metrics(types(), states, max_steps=7)
    assert_same(env, ours)
    assert ours["subtask_success"] == [1.0, 0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="after the episode ended"):
        goat_metrics(types(), states + [states[-1]], max_steps=7)


def test_type_success_counts_a_missing_type_as_zero():
    tasks, goals = TASKS[:2] + TASKS[3:], GOALS[:2] + GOALS[3:]  # no image subtask
    actions = [F, F, F, F, SUB, R, F, F, SUB, L, F, F, F, F, R, F, F, F, F, SUB]
    env, states = run(actions, tasks, goals)
    ours = goat_metrics(types(tasks), states)
    assert_same(env, ours)
    assert ours["image_success"] == 0.0 and math.isnan(ours["image_success_corrected"])
    assert ours["object_success_corrected"] == 1.0


def test_dropped_description_goals_out_of_step():
    # goat_dataset.py drops a long description from goals, not from tasks: goals[k] then belongs to tasks[k+1]
    tasks = TASKS
    goals = [GOALS[0], GOALS[2], GOALS[3]]  # the description's goals are gone
    actions = [F, F, F, F, SUB, R, F, F, L, F, F, F, F, SUB]  # to goals[1] (the image's) while tasks[1] is text
    env, states = run(actions + [STOP], tasks, goals)
    ours = goat_metrics(types(tasks), states, num_goals=len(goals))
    assert_same(env, ours)
    assert ours["subtask_success"] == [1.0, 1.0, 0.0, 0.0] and ours["description_success"] == 1.0
    # closing goals' last subtask: the reference indexes goals[len(goals)] and fails; navbench ends the episode
    with pytest.raises(IndexError):
        run(actions + [R, F, F, F, F, SUB], tasks, goals)
    states = run(actions + [R, F, F, F, F], tasks, goals)[1] + [(SUB, [1.5, 0.0, -2.0], float("nan"))]
    ours = goat_metrics(types(tasks), states, num_goals=len(goals))
    assert ours["subtask_success"] == [1.0, 1.0, 1.0, 0.0] and ours["subtasks_closed"] == 3


def test_zero_start_distance_is_defined():
    # a subtask whose target is the one just reached starts at distance 0; closing it without a move divides
    # 0 by 0 in the reference (ZeroDivisionError); navbench scores it as reached on the shortest path
    tasks = [TASKS[0], ["chair", "object", None]]
    goals = [GOALS[0], GOALS[0]]
    with pytest.raises(ZeroDivisionError):
        run([F, F, F, F, SUB, SUB], tasks, goals)
    states = run([F, F, F, F, SUB], tasks, goals)[1]
    ours = goat_metrics(types(tasks), states + [(SUB, states[-1][1], 0.0)])
    assert ours["subtask_success"] == [1.0, 1.0] and ours["spl_by_subtask"] == [1.0, 1.0]


def test_bad_input():
    with pytest.raises(ValueError):
        goat_metrics([], [(None, [0, 0, 0], 1.0)])
    with pytest.raises(ValueError):
        goat_metrics(["object"], [(1, [0, 0, 0], 1.0)])
    with pytest.raises(ValueError):
        goat_metrics(["chair"], [(None, [0, 0, 0], 1.0)])
    assert np.isclose(goat_metrics(["object"], [(None, [0, 0, 0], 0.1), (SUB, [0, 0, 0], 0.1)])["composite_spl"], 1.0)


def test_a_summary_leaves_undefined_corrected_type_success_out_of_its_mean():
    from navbench.metrics import aggregate

    base = {"success": 1.0, "spl": 1.0, "soft_spl": 1.0, "distance_to_goal": 0.0}
    rows = [dict(base, episode_id="0", image_success=0.0, image_success_corrected=None),  # no image subtask
            dict(base, episode_id="1", image_success=1.0, image_success_corrected=1.0)]
    out = aggregate(rows, keys=("success", "image_success", "image_success_corrected"))
    assert out["image_success"] == 0.5 and out["image_success_corrected"] == 1.0


# ---------------------------------------------------------------- GoatMeasures: goat_metrics one state at a time

def same(a, b):
    """Equal measures, NaN equal to NaN (d0 of a subtask never started, a corrected rate of a missing type)."""
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return type(a) is type(b) and a == b


def assert_incremental_equal(subtask_types, states, **kw):
    """GoatMeasures fed ``states`` one by one equals goat_metrics on every prefix, exactly."""
    inc = GoatMeasures(subtask_types, kw.get("num_goals"), kw.get("success_distance", 0.25), kw.get("max_steps"))
    inc.reset(states[0])
    for i in range(len(states)):
        if i:
            inc.step(states[i])
        ref_out, ours = goat_metrics(subtask_types, states[:i + 1], **kw), inc.result()
        assert ref_out.keys() == ours.keys()
        bad = [k for k in ref_out if not same(ref_out[k], ours[k])]
        assert not bad, (i, {k: (ref_out[k], ours[k]) for k in bad})


SCRIPTS = [
    (ORACLE, TASKS, GOALS, {}),
    ([F, F, R, F, F, L, F, SUB, F, F, SUB, SUB, F, F, F, SUB], TASKS, GOALS, {}),
    ([F, F, F, F, SUB, R, F, STOP], TASKS, GOALS, {}),
    ([F, UP, DOWN, F, F, F, SUB, R, R, F], TASKS, GOALS, {}),
    (ORACLE, TASKS, GOALS, {"max_steps": 7}),
    ([F, F, F, F, SUB, R, F, F, L, F, F, F, F, SUB, STOP], TASKS, [GOALS[0], GOALS[2], GOALS[3]], {}),
]


@pytest.mark.parametrize("actions,tasks,goals,kw", SCRIPTS)
def test_incremental_measures_equal_goat_metrics_on_scripts(actions, tasks, goals, kw):
    _, states = run(actions, tasks, goals, max_steps=kw.get("max_steps", 5000))
    num_goals = len(goals) if len(goals) < len(tasks) else None
    assert_incremental_equal(types(tasks), states, num_goals=num_goals, **kw)


@pytest.mark.parametrize("seed", range(20))
def test_incremental_measures_equal_goat_metrics_on_random_sequences(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 8))
    tasks = [str(t) for t in rng.choice(["object", "description", "image"], n)]
    goals = int(rng.integers(1, n + 1))
    pos = rng.normal(size=3)
    states = [(None, pos.tolist(), float(rng.uniform(0, 5)))]
    closed = 0
    for i in range(int(rng.integers(1, 300))):
        a = int(rng.choice([1, 2, 3, 4, 5, 6, 0], p=[.4, .15, .15, .05, .05, .18, .02]))
        closed += a == SUB
        if a == F:
            pos = pos + rng.normal(scale=0.25, size=3)
        d = float(rng.choice([rng.uniform(0, 0.3), rng.uniform(0, 5), 0.0])) if closed < goals else float("nan")
        states.append((a, pos.tolist(), d))
        if a == STOP or closed >= goals or i + 1 >= 250:
            break
    assert_incremental_equal(tasks, states, num_goals=goals, success_distance=0.25, max_steps=250)
    inc = GoatMeasures(tasks, goals, 0.25, 250)
    inc.reset(states[0])
    for s in states[1:]:
        inc.step(s)
    with pytest.raises(ValueError, match="after the episode ended"):
        inc.step(states[-1]) if inc.ended else goat_metrics(tasks, states + [states[-1]] * 251, num_goals=goals,
                                                           max_steps=250)
