"""The documentation site: it builds with Sphinx with warnings as errors and every on-site link and anchor
resolves (scripts/docs.py); the generated plant pages come from the code (ids, units, scenarios); the
link check finds a broken link and a missing anchor; the frames show each plant on a lit floor."""

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from frictiongym.scripts import docs

ROOT = Path(__file__).parents[1]
pytest.importorskip("sphinx", reason="the docs extra: pip install -e '.[docs]'")


def test_the_link_check_finds_a_missing_page_and_a_missing_anchor(tmp_path):
    (tmp_path / "a.html").write_text('<h1 id="top">a</h1><a href="b.html#there">b</a><a href="#top">t</a>')
    (tmp_path / "b.html").write_text('<p id="here"></p><a href="c.html">c</a><img src="_static/x.png">'
                                     '<a href="https://example.org/x">out</a><a href="a.html#top">a</a>')
    assert docs.broken_links(tmp_path) == [
        "a.html: b.html#there (no such anchor)", "b.html: c.html", "b.html: _static/x.png"]
    (tmp_path / "c.html").write_text("")
    (tmp_path / "b.html").write_text('<a href="a.html#top">a</a>')
    (tmp_path / "a.html").write_text('<h1 id="top">a</h1><a href="b.html">b</a>')
    assert docs.broken_links(tmp_path) == []


@pytest.mark.slow
def test_the_site_builds_without_warnings_and_its_links_resolve(tmp_path):
    site = tmp_path / "site"
    assert docs.build(site) == []
    pages = {p.relative_to(site).as_posix() for p in site.rglob("*.html")}
    assert {"index.html", "installation.html", "quickstart.html", "changelog.html", "troubleshooting.html",
            "tutorials/index.html", "generated/api/index.html", "generated/scenarios.html",
            "leaderboard/index.html"} <= pages  # fmt: skip
    for plant, env_id in [("m220", "frictiongym/M220-v1"), ("emps", "frictiongym/EMPS-v1")]:
        page = (site / "generated" / "plants" / f"{plant}.html").read_text()
        assert env_id in page and f"_images/{plant}.png" in page
        assert (site / "_images" / f"{plant}.png").is_file()
    emps = (site / "generated" / "plants" / "emps.html").read_text()
    # the carriage's identified mass with its unit (a slide: kg, not kg·m²), its scenarios' ids
    assert "95.11 kg" in emps and "frictiongym/EMPS-Tracking-v1" in emps
    api = site / "generated" / "api"
    assert 'id="frictiongym.agents.registry.make"' in (api / "frictiongym.agents.registry.html").read_text()
    assert 'id="frictiongym.envs.servo_env.ServoEnv"' in (api / "frictiongym.envs.servo_env.html").read_text()
    assert 'href="frictiongym.agents.evaluation.evaluate.html"' in (api / "index.html").read_text()
    # a docstring's bullet list is a list, not a literal block: frictiongym.envs's two kinds of id
    envs = (api / "frictiongym.envs.html").read_text()
    assert re.search(r"<ul[^>]*>\s*<li><p>one per plant", envs), "the docstring's list is not a list"
    # a file the reader saves is highlighted as Python, not as a shell heredoc
    assert "highlight-python" in (site / "tutorials" / "your-controller.html").read_text()
    changelog = (site / "changelog.html").read_text()
    assert "v0" in changelog and "Unreleased" in changelog  # the env versions and the releases


@pytest.mark.slow
def test_render_writes_a_frame_per_plant_showing_the_scene(tmp_path):
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    proc = subprocess.run([sys.executable, str(ROOT / "scripts/render.py"), "--out", str(tmp_path)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    import matplotlib.image

    for plant in ("m220", "flexible_servo", "kang_robot", "emps"):
        img = matplotlib.image.imread(tmp_path / f"{plant}.png")[..., :3]
        assert img.shape == (480, 640, 3)
        # a lit scene: the sky and the floor, not the empty black of a bare model
        assert img.mean() > 0.5 and (img.max(axis=2) < 0.05).mean() < 0.01
        # the mechanism is in the middle: every moving part carries a red marker, and their pixels'
        # centroid lies in the middle third of the frame both ways
        red = (img[..., 0] > 0.6) & (img[..., 1] < 0.45) & (img[..., 2] < 0.4)
        ys, xs = np.nonzero(red)
        assert len(xs) > 100 and 213 < xs.mean() < 427 and 160 < ys.mean() < 320, plant
