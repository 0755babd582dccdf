"""Test markers: `slow` marks a test that is slow for a reason, said beside its mark: it trains or tunes,
runs a suite, a leaderboard with its figures or a study (identification, a reproduction of a document's
numbers, a stiff ODE reference), starts fresh interpreters, a process pool or a service, or sends real
signals; the inner loop is `python -m pytest -m "not slow"` (about a minute on 2 cores), CI runs
everything. Helpers shared by test modules: `lockstep` (single vs vector env bit for bit) and
`write_config` (a small training config, test_training and test_learned), `load_script` (a front end of
scripts/ as a module, for its functions), `bit_flips` (a sealed file's single-bit corruptions,
test_model_trust and test_runtime)."""

import importlib.util
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import yaml


def bit_flips(data: bytes, count: int) -> Iterator[tuple[int, bytes]]:
    """(position, data with one random bit flipped there) at `count` distinct random positions, drawn
    from a generator seeded with the data's length (the same sweep every run)."""
    rng = np.random.default_rng(len(data))
    for pos in rng.choice(len(data), size=count, replace=False):
        flipped = bytearray(data)
        flipped[pos] ^= 1 << int(rng.integers(8))
        yield int(pos), bytes(flipped)


def load_script(name: str) -> ModuleType:
    """scripts/<name>.py loaded as a module (scripts/ is not a package), its main() not run."""
    path = Path(__file__).parents[1] / "scripts" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def pytest_configure(config):
    # the friction-free optimum's programs (agents/evaluation/optimum.py) are kept in a folder of the
    # test session's own, shared by its workers and the interpreters its tests start, never the user's
    from frictiongym.agents.evaluation.optimum import CACHE_VARIABLE

    if CACHE_VARIABLE not in os.environ:
        os.environ[CACHE_VARIABLE] = _MADE[0] = tempfile.mkdtemp(prefix="frictiongym-test-cache-")
    config.addinivalue_line(
        "markers", "slow: slow for the reason beside its mark (deselect: -m 'not slow')"
    )


def pytest_unconfigure(config):
    if _MADE[0]:  # the process that made the session's cache folder removes it
        shutil.rmtree(_MADE[0], ignore_errors=True)


_MADE: list[str] = [""]


def lockstep(scenario: str, kw: dict, keys: tuple[str, ...], copy_at: int, seed: int = 20) -> list:
    """Two single envs and a 2-env vector env of `scenario` (constructor arguments kw) stepped with the
    same random actions over an episode: equal observations, rewards and ground truth `keys` at every step
    (bit for bit), and a pickled copy of the first single env, taken after step copy_at, continues as it
    did. Returns the single envs (at the episode's last step)."""
    import pickle

    import numpy as np

    from frictiongym.envs.servo_env import ServoEnv
    from frictiongym.envs.vector import ServoVectorEnv

    v = ServoVectorEnv(scenario, 2, nthread=2, **kw)
    singles = [ServoEnv(scenario, **kw) for _ in range(2)]
    o, _ = v.reset(seed=seed)
    for i, s in enumerate(singles):
        assert np.array_equal(s.reset(seed=seed + i)[0], o[i])
    rng = np.random.default_rng(0)
    twin, after = None, []
    for step in range(v.scenario.episode_steps - 1):
        a = rng.uniform(-1, 1, (2, 1)).astype(np.float32)
        o, r, *_ = v.step(a)
        truth = v.ground_truth()
        for i, s in enumerate(singles):
            oi, ri, *_ = s.step(a[i])
            assert np.array_equal(o[i], oi) and r[i] == ri
            gt = s.ground_truth()
            for key in keys:
                assert np.array_equal(truth[key][i], gt[key]), key
        if twin is not None:
            after.append((a[0], o[0]))
        if step == copy_at:  # a copy taken mid-episode
            twin = pickle.loads(pickle.dumps(singles[0]))
    for a, o0 in after:  # continues bit for bit
        assert np.array_equal(twin.step(a)[0], o0)
    return singles


# ------------------------------------------------------------------ small training configs
SCENARIO = "flexible_speed_step"  # 250 steps per episode: the cheapest validation episodes
HYPER = {
    "SAC": {"learning_starts": 0, "batch_size": 32, "buffer_size": 2000, "policy_kwargs": {"net_arch": [16]}},
    "TD3": {"learning_starts": 0, "batch_size": 32, "buffer_size": 2000, "action_noise_std": 0.01},
    "TQC": {"learning_starts": 0, "batch_size": 32, "buffer_size": 2000, "policy_kwargs": {"n_critics": 2}},
    "CrossQ": {
        "learning_starts": 0,
        "batch_size": 32,
        "buffer_size": 2000,
        "policy_kwargs": {"net_arch": [16]},
    },
    "sbx.SAC": {
        "learning_starts": 0,
        "batch_size": 32,
        "buffer_size": 2000,
        "policy_kwargs": {"net_arch": [16]},
    },
    "sbx.CrossQ": {
        "learning_starts": 0,
        "batch_size": 32,
        "buffer_size": 2000,
        "policy_kwargs": {"net_arch": [16]},
    },
    "PPO": {"n_steps": 128, "batch_size": 64, "n_epochs": 1},
    "RecurrentPPO": {"n_steps": 128, "batch_size": 64, "n_epochs": 1},
}


def write_config(tmp_path: Path, algo: str, steps: int = 256, **extra) -> Path:
    entry = {"residual": {"base": "PID", "alpha": 0.1}, **extra}
    cfg = {
        "name": f"Smoke{algo.replace('.', '_')}",
        "algorithm": algo,
        "defaults": {
            "total_timesteps": steps,
            "validation": {"every_steps": 128, "episodes": 2, "max_effort_ratio": 100.0},
            "hyperparams": HYPER[algo],
        },
        "scenarios": {SCENARIO: entry},
    }
    path = tmp_path / f"{algo}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path
