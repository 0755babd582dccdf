"""Test markers: `slow` marks a test that trains, runs a suite or a study (identification, a stiff ODE
reference), sends real signals or starts a service; the inner loop is `python -m pytest -m "not slow"`,
CI runs everything."""


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow: trains, runs a suite or starts a service (deselect: -m 'not slow')"
    )


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
