"""The study's interfaces driven through the dashboard's page: hands for the study's own
operator.

The browser study (``tests/ui/test_ui_study_browser.py``) runs the simulated study's
planner, :class:`wovenskin.operators.operator.SimulatedOperator`, with
:data:`EXPERIMENTER` (an experimenter who knows the task: no thinking, no hesitation, no
wrong way), stepped on the session's clock by
:func:`wovenskin.operators.script.run_blocking` from the test's thread.  Its hand is a
:class:`PageHand`: each act is carried out in the page by a driver, then it waits until
the session has counted the commands the act sent (a page's input takes its way through
the browser, the websocket and the server; on a loaded machine a second or more).

The driver interface (one class per study interface; the skin's is in ``skin_driver.py``)::

    class Driver(Protocol):
        interface: str                  # the page's interface name: "keyboard", ...
        exact_nudges: bool              # a nudge moves exactly its amount or less
        def prepare(self) -> None: ...  # choose the interface in the page, set it up
        def press(self, axis: str, sign: int) -> int: ...  # start moving; held until
        def release(self) -> None: ...                     # ... this stops it
        def nudge(self, axis: str, sign: int, amount: float) -> int: ...  # a short move
        def gripper(self) -> int: ...   # toggle the gripper

``axis`` is a BASE-frame axis as the operator's hands take it (``x``, ``y``, ``z``, m;
``rx``, ``ry``, ``rz`` about the TCP, rad; ``sign`` +1 or -1); a driver of a tool-frame
interface picks the command whose axis best matches now
(:func:`wovenskin.operators.hands.tool_command`).  ``press``, ``nudge`` and ``gripper``
return how many commands they sent (a release is none).  :class:`ServerView` reads the
state the server publishes to the page, for the page's own settings.
"""

from __future__ import annotations

import math
import time
from typing import Protocol

from wovenskin.operators.hands import ROTATIONS, press_time, tool_command
from wovenskin.operators.profiles import OperatorProfile
from wovenskin.operators.script import Plan, Until
from wovenskin.teleop.keyboard import key_map

# an experimenter operating a study scene it knows: it reacts, aims and learns as the
# study's experts do, but spends no time thinking, pointing or finding keys (the page's
# own latency stands in for them), and never starts the wrong way
EXPERIMENTER = OperatorProfile(
    name="experimenter", expertise="expert", think_s=0.0, reaction_s=0.12, anticipation=1.0,
    key_s=0.0, point_s=0.0, home_s=0.0, wrong_direction=0.0, hesitation=0.0, practice=0.0,
    precision=0.8, seed=0,
)  # fmt: skip
COUNTED_S = 60.0  # the longest a page's command may take to reach the session


class Driver(Protocol):
    """See the module docstring."""

    interface: str

    def prepare(self) -> None: ...

    def press(self, axis: str, sign: int) -> int: ...

    def release(self) -> None: ...

    def nudge(self, axis: str, sign: int, amount: float) -> int: ...

    def gripper(self) -> int: ...


class OperatorError(AssertionError):
    """A step in the page did not happen (a test failure with what was seen)."""


class ServerView:
    """The session's newest state as the server publishes it (``runner.latest()``)."""

    def __init__(self, runner) -> None:
        self.runner = runner

    def state(self) -> dict:
        return self.runner.latest() or {}

    def wait(self, predicate, timeout_s: float, what: str) -> dict:
        """The first state for which ``predicate`` holds; OperatorError after the timeout."""
        deadline = time.monotonic() + timeout_s
        while True:
            state = self.state()
            try:
                if state and predicate(state):
                    return state
            except (KeyError, TypeError, IndexError):
                pass
            if time.monotonic() > deadline:
                raise OperatorError(f"timed out after {timeout_s} s waiting for {what}")
            time.sleep(0.02)

    def task_state(self, state: dict | None = None) -> dict:
        return (state or self.state())["task"]["state"]


class PageHand:
    """A page driver as the operator's hand (module docstring): the same acts as
    :class:`wovenskin.operators.hands.Hand`'s, each a plan."""

    scale = 1.0  # the drivers move at the page's full speed setting
    wrong = 0

    def __init__(self, driver: Driver, session) -> None:
        self.driver, self.session = driver, session
        self.interface = driver.interface
        self.tool_frame = not driver.exact_nudges  # a step moves its increment

    def _counted(self, act) -> Plan:
        before = self.session.command_count
        sent = act()
        yield Until(
            lambda: self.session.command_count >= before + sent, COUNTED_S, "the command counted"
        )
        return sent

    def press(self, axis: str, sign: int, distance: float = math.inf) -> Plan:
        return (yield from self._counted(lambda: self.driver.press(axis, sign)))

    def nudge(self, axis: str, sign: int, amount: float) -> Plan:
        return (yield from self._counted(lambda: self.driver.nudge(axis, sign, amount)))

    def gripper(self) -> Plan:
        return (yield from self._counted(self.driver.gripper))

    def release(self) -> Plan:
        self.driver.release()
        return 0
        yield  # a plan

    def release_now(self) -> None:
        self.driver.release()


# -- the page's interfaces (Playwright)


def choose(page, selector: str, value: str) -> None:
    """Choose an option of a select as a person does (its change event), in one script
    (``select_option`` waits for a stable frame, a second or more on a busy page)."""
    page.evaluate(
        "([selector, value]) => { const s = document.querySelector(selector);"
        " s.value = value; s.dispatchEvent(new Event('change')); }",
        [selector, value],
    )


class PageDriver:
    """What the page drivers share: the page, the server's view, the interface choice."""

    interface = ""
    exact_nudges = False

    def __init__(self, page, view: ServerView) -> None:
        self.page = page
        self.view = view

    def prepare(self) -> None:
        self.page.select_option("#interface", self.interface)
        self.view.wait(
            lambda s: s["teleop"]["interface"] == self.interface, 30, "the interface choice"
        )
        self.page.evaluate("document.activeElement && document.activeElement.blur()")


class KeyboardDriver(PageDriver):
    """The page's keys (``page.keyboard``), tool frame: for a base-frame axis the key of
    the tool axis that best matches it now, with the sign of their alignment."""

    interface = "keyboard"

    def __init__(self, page, view: ServerView, session) -> None:
        super().__init__(page, view)
        self.session = session
        self.keys = {row.action: row.key for row in key_map(session.mapping)}
        settings = session.mapping.settings
        self.speed = {"linear": settings.linear_speed, "angular": settings.angular_speed}
        self.accel = {"linear": settings.linear_accel, "angular": settings.angular_accel}
        self.held: str | None = None

    def key(self, axis: str, sign: int) -> str:
        return self.keys[tool_command(self.session, axis, sign)]

    def press(self, axis: str, sign: int) -> int:
        self.held = self.key(axis, sign)
        self.page.keyboard.down(self.held)
        return 1

    def release(self) -> None:
        if self.held is not None:
            self.page.keyboard.up(self.held)
            self.held = None

    def nudge(self, axis: str, sign: int, amount: float) -> int:
        """A tap as long as a ramped move of ``amount`` takes (:func:`press_time`)."""
        key = self.key(axis, sign)
        kind = "angular" if axis in ROTATIONS else "linear"
        held = press_time(amount, self.speed[kind], self.accel[kind])
        self.page.keyboard.down(key)
        time.sleep(min(0.6, max(0.02, held)))
        self.page.keyboard.up(key)
        return 1

    def gripper(self) -> int:
        self.page.keyboard.press("g")
        return 1


class PendantDriver(PageDriver):
    """The page's jog panel in the base frame at 100 % speed: a jog button held with the
    mouse for long moves, step mode (10, 5, 1 mm or deg per click) for short ones."""

    interface = "pendant"
    exact_nudges = True  # a step moves its increment: the operator need not learn a gain

    def prepare(self) -> None:
        super().prepare()
        self._choose("#jog-frame", "base")
        self.page.evaluate(
            "(() => { const s = document.getElementById('jog-speed'); s.value = 100;"
            " s.dispatchEvent(new Event('change')); })()"
        )
        self.view.wait(
            lambda s: (
                s["teleop"]["pendant"]["speed_percent"] == 100
                and s["teleop"]["pendant"]["frame"] == "base"
            ),
            30,
            "the pendant's settings",
        )
        self.step: int | None = -1  # unknown: the first _mode sets it
        self._mode(None)

    def _mode(self, size: int | None) -> int:
        """Step mode ``size`` (None: continuous jog); returns the commands it took."""
        if self.step == size:
            return 0
        self._choose("#jog-step", "off" if size is None else str(size))
        self.step = size
        # the person sees the panel in that mode before pressing (a page drawing an older
        # state would set the select back, and a press would then not be held)
        wanted = "null" if size is None else str(size)
        self.page.wait_for_function(
            "window.wovenskin.state.teleop.pendant"
            f" && window.wovenskin.state.teleop.pendant.step_size === {wanted}",
            timeout=60000,
        )
        return 1

    def _choose(self, selector: str, value: str) -> None:
        choose(self.page, selector, value)

    def _at(self, selector: str) -> None:
        """Put the mouse over an element, scrolled into view.  Mouse events, and the
        element's box read by one script: on a page busy drawing its 3D view on the CPU,
        Playwright's click and bounding_box wait a second or more for a stable frame."""
        x, y = self.page.evaluate(
            """(selector) => {
                const element = document.querySelector(selector);
                let r = element.getBoundingClientRect();
                if (r.top < 0 || r.bottom > window.innerHeight) {
                    element.scrollIntoView({ block: "center" });
                    r = element.getBoundingClientRect();
                }
                return [r.left + r.width / 2, r.top + r.height / 2];
            }""",
            selector,
        )
        self.page.mouse.move(x, y)

    def _button(self, axis: str, sign: int) -> None:
        self._at(f'#jog-axes button[data-axis="{axis}"][data-sign="{sign}"]')

    def press(self, axis: str, sign: int) -> int:
        sent = self._mode(None)
        for _ in range(3):  # a press the panel did not take is pressed again, as people do
            self._button(axis, sign)
            self.page.mouse.down()
            try:
                self.view.wait(
                    lambda s: s["teleop"]["pendant"]["jogging"] is not None, 5, "the jog"
                )
                return sent + 1
            except (OperatorError, KeyError, TypeError):
                self.page.mouse.up()
        raise OperatorError(f"the {axis} {sign:+d} jog button did not take three presses")

    def release(self) -> None:
        self.page.mouse.up()

    def nudge(self, axis: str, sign: int, amount: float) -> int:
        unit = amount * (math.degrees(1) if axis in ROTATIONS else 1000.0)
        size = max(s for s in (1, 5, 10) if s <= max(unit, 1.0))
        sent = self._mode(size)
        self._button(axis, sign)
        self.page.mouse.down()
        self.page.mouse.up()
        return sent + 1

    def gripper(self) -> int:
        self._at("#jog-gripper")
        self.page.mouse.down()
        self.page.mouse.up()
        return 1
