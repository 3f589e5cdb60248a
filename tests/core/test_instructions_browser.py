"""instructions.html in a real browser: headless Chromium (Debian chromium + chromium-driver)
driven by selenium; keys, slider, play mode and a touch swipe change the visible step."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest

from core import pipeline
from core.instructions import page as instructions

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
from conftest import HMD_HIGH_RES

ROOT = Path(__file__).resolve().parents[2]

webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed (pip install selenium)")
if not (Path(CHROMIUM).is_file() and Path(CHROMEDRIVER).is_file()):
    pytest.skip("chromium and chromedriver are not installed (apt-get install chromium chromium-driver)",
                allow_module_level=True)

from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402

#: Headless Chromium on the fabricated demo: left out of make test-quick.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def assembly(tmp_path_factory, hmd_step):
    fab = pipeline.run(hmd_step, high_res=HMD_HIGH_RES, slice_parts=False)
    out = tmp_path_factory.mktemp("assembly")
    result = instructions.write_assembly(fab.layout, fab.printed, out, title="hmd")
    steps: dict[int, set[int]] = {}
    for b in fab.layout.bricks:
        steps.setdefault(b.step, set()).add(b.id)
    return out / "instructions.html", steps, fab, result


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = tmp_path_factory.mktemp("chromium-profile")
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run",
                "--disable-dev-shm-usage", f"--user-data-dir={profile}", "--window-size=1280,800"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture
def page(browser, assembly):
    browser.get(Path(assembly[0]).as_uri())
    WebDriverWait(browser, 10).until(lambda d: d.execute_script("return !!window.fabrickator"))
    return browser


def state(driver) -> dict:
    """What the page shows: step number, layer, and brick ids per class (visible or not)."""
    return driver.execute_script("""
        const ids = cls => Array.from(document.querySelectorAll('#bricks > g.' + cls))
            .map(g => +g.getAttribute('data-id'));
        const shown = Array.from(document.querySelectorAll('#bricks > g'))
            .filter(g => getComputedStyle(g).display !== 'none').map(g => +g.getAttribute('data-id'));
        return {step: +document.getElementById('stepno').textContent,
                layer: +document.getElementById('layerno').textContent,
                now: ids('now'), done: ids('done'), todo: ids('todo'), shown: shown,
                callout: document.getElementById('callout').innerText};
    """)


def press(driver, key) -> None:
    driver.find_element(By.TAG_NAME, "body").send_keys(key)


def expect_step(driver, steps, n) -> dict:
    s = state(driver)
    assert s["step"] == n
    assert set(s["now"]) == steps[n]
    assert set(s["done"]) == set().union(*(steps[k] for k in steps if k < n))
    assert set(s["shown"]) == set(s["now"]) | set(s["done"])
    return s


def test_keys_step_through_the_assembly(page, assembly):
    _, steps, fab, result = assembly
    expect_step(page, steps, 1)
    press(page, Keys.ARROW_RIGHT)
    s = expect_step(page, steps, 2)
    layer = min(b.cell[2] for b in fab.layout.bricks if b.id in steps[2])
    assert s["layer"] == layer + 1
    press(page, Keys.ARROW_RIGHT)
    expect_step(page, steps, 3)
    press(page, Keys.ARROW_LEFT)
    expect_step(page, steps, 2)
    press(page, Keys.END)
    s = expect_step(page, steps, result["steps"])
    assert s["todo"] == []
    press(page, Keys.ARROW_RIGHT)                      # past the end stays at the end
    expect_step(page, steps, result["steps"])
    press(page, Keys.HOME)
    expect_step(page, steps, 1)


def test_highlight_colours_and_printed_part_step(page, assembly):
    _, steps, fab, _ = assembly
    part = fab.printed[0]
    n = next(k for k, ids in steps.items() if ids == set(part.bricks))
    page.execute_script(
        "const s = document.getElementById('slider'); s.value = arguments[0];"
        "s.dispatchEvent(new Event('input'));", n)
    s = expect_step(page, steps, n)
    assert f"Insert printed part {part.id}" in s["callout"]
    assert (f"find the ID {part.id} engraved on its side" in s["callout"]) is part.engraved
    fills = page.execute_script("""
        const f = sel => { const e = document.querySelector(sel); return e ? getComputedStyle(e).fill : null; };
        return {now_side: f('#bricks > g.now path.m0'), done_side: f('#bricks > g.done:not(.pp) .l'),
                done_top: f('#bricks > g.done:not(.pp) .t'),
                label: getComputedStyle(Array.from(document.querySelectorAll('#labels text'))
                    .find(t => t.textContent === arguments[0])).display};
    """, part.id)
    hexrgb = lambda h: "rgb({}, {}, {})".format(*(int(h[i:i + 2], 16) for i in (1, 3, 5)))
    assert fills["now_side"] == hexrgb(instructions.PRINTED[1])   # its mesh's darkest shade
    assert fills["done_side"] == hexrgb(instructions.LEGO_DONE[1])
    assert fills["done_top"].startswith("url(")          # studs pattern on built tops
    assert fills["label"] != "none"
    page.execute_script("window.fabrickator.show(1)")
    lego_step = next(k for k in sorted(steps) if k > 1 and not steps[k] & {b for p in fab.printed for b in p.bricks})
    page.execute_script("window.fabrickator.show(arguments[0])", lego_step)
    fill = page.execute_script("return getComputedStyle(document.querySelector('#bricks > g.now .l')).fill")
    assert fill == hexrgb(instructions.LEGO_NOW[1])


def test_space_plays_and_pauses(page, assembly):
    _, steps, _, _ = assembly
    press(page, Keys.SPACE)
    WebDriverWait(page, 3 * instructions.PLAY_MS / 1000 + 2).until(lambda d: state(d)["step"] >= 3)
    press(page, Keys.SPACE)
    assert page.execute_script("return window.fabrickator.playing()") is False
    n = state(page)["step"]
    time.sleep(instructions.PLAY_MS / 1000 + 0.3)
    expect_step(page, steps, n)


def test_swipe_left_goes_forward_and_right_goes_back(page, assembly):
    _, steps, _, _ = assembly
    page.execute_cdp_cmd("Emulation.setTouchEmulationEnabled", {"enabled": True, "maxTouchPoints": 1})

    def swipe(x0, x1):
        for kind, x in (("touchStart", x0), ("touchMove", (x0 + x1) / 2), ("touchMove", x1)):
            page.execute_cdp_cmd("Input.dispatchTouchEvent",
                                 {"type": kind, "touchPoints": [{"x": x, "y": 300}]})
        page.execute_cdp_cmd("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})

    swipe(700, 300)
    WebDriverWait(page, 3).until(lambda d: state(d)["step"] == 2)
    expect_step(page, steps, 2)
    swipe(300, 700)
    WebDriverWait(page, 3).until(lambda d: state(d)["step"] == 1)
    swipe(500, 490)                                    # a tap is not a swipe
    time.sleep(0.2)
    expect_step(page, steps, 1)


def test_no_errors_in_the_console(page):
    press(page, Keys.ARROW_RIGHT)
    errors = [e for e in page.get_log("browser") if e.get("level") == "SEVERE"]
    assert errors == []


def test_a_prop_shows_from_the_step_it_is_stood_before_to_the_step_it_goes(browser, tmp_path):
    """A bridge on a table, with a row of 2x4 bricks on it, is built on props (the tests of
    the build order say why).  The page draws each prop, says where to stand it at its step
    and when to take it away, and shows it from the one step to the other."""
    from test_forces import layout_of, long_bridge
    from core import forces
    from core.instructions import build_order
    from core.model import Brick
    bridge = long_bridge(3)
    lay = layout_of(bridge.bricks + [Brick(len(bridge.bricks) + 1 + n, "3001", (4, 2, 3), (4 * n, 0, 5))
                                     for n in range(7)])
    order = build_order.standing(lay, build_order.plan(lay, bricks_per_step=1),
                                 forces.BuildChecker(lay, ground="table").stands, lookahead=4, props=True)
    props = order.props
    assert len(props) >= 1 and order.unstable == []
    assert all(p["removed_after"] is not None and p["removed_after"] < len(order.steps) for p in props)
    instructions.write_assembly(lay, [], tmp_path, order=order)
    browser.get((tmp_path / "instructions.html").as_uri())
    WebDriverWait(browser, 10).until(lambda d: d.execute_script("return !!window.fabrickator"))
    for n in range(1, len(order.steps) + 1):
        browser.execute_script("window.fabrickator.show(arguments[0])", n)
        shown = browser.execute_script("""return Array.from(document.querySelectorAll('#props > g'))
            .map(g => getComputedStyle(g).display !== 'none');""")
        assert shown == [p["step"] <= n <= p["removed_after"] for p in props], n
        said = browser.find_element(By.ID, "attach").text
        assert ("Prop: before step" in said) == any(p["step"] == n for p in props), n
        assert ("take away the prop" in said) == any(p["removed_after"] == n for p in props), n
