"""Test markers: `slow` marks a test that trains, runs a suite or a study (identification, a stiff ODE
reference), sends real signals or starts a service; the inner loop is `python -m pytest -m "not slow"`,
CI runs everything."""


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow: trains, runs a suite or starts a service (deselect: -m 'not slow')"
    )
