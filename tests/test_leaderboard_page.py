"""The leaderboard's web page (index.html, agents/evaluation/page.py): self-contained (no network), every
table sortable, the reference rows marked; and in a real browser (Debian's chromium, headless, driven by
Selenium): it loads without console errors, a table sorts on a click, every image loads, a screenshot is
written as an artefact. The browser test needs chromium and chromedriver (.ci/run installs them and sets
FRICTIONGYM_REQUIRE_BROWSER=1, so there a missing browser fails instead of skipping)."""

from __future__ import annotations

import base64
import os
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import pytest

from frictiongym.agents.evaluation import leaderboard
from frictiongym.envs.suites import Episode

EPISODES = [Episode(sc, s, True) for sc in ("kang_ramp", "m220_regulation") for s in (5000, 5001)]


@pytest.fixture(scope="module")
def board_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("board")
    leaderboard.run(
        controllers=["PID+FF", "Southward"], out=out, progress=False, episodes=EPISODES, judge=False
    )
    return out


class Page(HTMLParser):
    """The page's tables (their header cells and row classes), images and external references."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[dict] = []
        self.images: list[str] = []
        self.external: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        for key in ("src", "href"):
            if a.get(key) and re.match(r"[a-z]+://", a[key] or ""):
                self.external.append(a[key] or "")
        if tag == "table":
            self.tables.append({"class": a.get("class"), "heads": 0, "rows": []})
        elif tag == "th":
            self.tables[-1]["heads"] += 1
        elif tag == "tr" and self.tables and self.tables[-1]["heads"]:
            self.tables[-1]["rows"].append(a.get("class") or "")
        elif tag == "img":
            self.images.append(a.get("src") or "")


@pytest.mark.slow  # a leaderboard and its page
def test_the_page_is_self_contained_with_sortable_tables_and_marked_references(board_dir):
    """Nothing is fetched (no http(s) or file address; figures are PNG data URIs), every table sorts,
    the question, the aggregates and each scenario have a table, and the reference rows carry class ref
    (Zero, Ideal, Oracle on both scenarios, TrackingLimit on the ramp: 7 reference rows)."""
    text = (board_dir / "index.html").read_text()
    page = Page()
    page.feed(text)
    assert page.external == []
    assert page.images and len(page.images) == len(list(board_dir.glob("*.png")))
    for src in page.images:
        head, data = src.split(",", 1)
        assert head == "data:image/png;base64" and base64.b64decode(data)[:8] == b"\x89PNG\r\n\x1a\n"
    assert all(t["class"] == "sortable" for t in page.tables)
    assert "<h3 id='kang_ramp'>kang_ramp</h3>" in text and "<h3 id='m220_regulation'>" in text
    scenario_rows = [r for t in page.tables[-2:] for r in t["rows"]]
    assert scenario_rows.count("ref") == 9  # Zero, Ideal, Oracle, Optimum on both; TrackingLimit on the ramp
    assert "<p class='provenance'>frictiongym: " in text and "; commit: " in text
    # the answer first, and every metric with its unit
    assert text.index("<h2 id='answer'>The answer</h2>") < text.index("<h2 id='question'>")
    assert "<li class='none'><b>kang_robot</b>: no learned or plug-in entry ran</li>" in text
    assert "<th>iae [rad·s] (main)</th>" in text and "<th>effort_rms [V rms]</th>" in text


def _chromium() -> tuple[str, str] | None:
    found = shutil.which("chromium"), shutil.which("chromedriver")
    return None if None in found else found  # type: ignore[return-value]


@pytest.mark.slow  # a leaderboard and a browser
def test_the_page_in_a_real_browser_loads_sorts_and_shows_every_image(board_dir, tmp_path):
    """Headless chromium opens index.html: no console error, every image decoded (naturalWidth > 0) with its
    text at least 9 px at the page's width, the answer first, the units in the headers, a
    click on a scenario table's main-metric header sorts its rows ascending by that column's values, a
    second click descending; a screenshot goes to $FRICTIONGYM_ARTEFACTS (else the test's folder)."""
    paths = _chromium()
    if paths is None:
        if os.environ.get("FRICTIONGYM_REQUIRE_BROWSER"):
            pytest.fail("FRICTIONGYM_REQUIRE_BROWSER is set but chromium or chromedriver is not on PATH")
        pytest.skip("needs chromium and chromedriver (Debian: apt-get install chromium chromium-driver)")
    from selenium import webdriver
    from selenium.webdriver.common.by import By

    options = webdriver.ChromeOptions()
    options.binary_location = paths[0]
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1280,2000"):  # fmt: skip
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(executable_path=paths[1]))
    try:
        driver.get((board_dir / "index.html").as_uri())
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert errors == []
        images = driver.find_elements(By.TAG_NAME, "img")
        widths = [driver.execute_script("return arguments[0].naturalWidth", i) for i in images]
        assert widths and min(widths) > 0
        # every figure's smallest text is at least 9 px as the page shows it (its natural size x the scale)
        for img, natural in zip(images, widths, strict=True):
            shown = driver.execute_script("return arguments[0].clientWidth", img)
            px = float(img.get_attribute("data-text-px")) * shown / natural
            assert px >= 9, f"{img.get_attribute('alt')}: text {px:.1f} px at the page's width"
        table = driver.find_element(By.CSS_SELECTOR, "h3#kang_ramp + p + table")
        header = table.find_elements(By.TAG_NAME, "th")[1]  # the main metric

        def column() -> list[float]:
            cells = table.find_elements(By.CSS_SELECTOR, "tbody tr td:nth-child(2)")
            return [float(c.get_attribute("data-v")) for c in cells]

        header.click()
        up = column()
        assert up == sorted(up) and len(up) >= 5
        header.click()
        assert column() == sorted(up, reverse=True)
        headline = driver.find_element(By.ID, "answer")
        assert headline.is_displayed() and headline.location["y"] < table.location["y"]
        assert "[rad·s]" in header.text  # the unit where the reader reads the number
        shots = Path(os.environ.get("FRICTIONGYM_ARTEFACTS", tmp_path))
        shots.mkdir(parents=True, exist_ok=True)
        assert driver.save_screenshot(str(shots / "leaderboard_page.png"))
    finally:
        driver.quit()
