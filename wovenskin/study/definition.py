"""A study's definition, ``study.toml``: tasks, interfaces, trials, time limit, participants."""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from annotated_types import Ge, Gt

from wovenskin.errors import ConfigError
from wovenskin.io import atomic_write_text
from wovenskin.outputs import check_new_output, check_writable
from wovenskin.settings import from_dict

STUDY_FILE = "study.toml"
TIME_LIMIT_S = 300.0
"""A trial's time limit, seconds from its first command (the default of
:attr:`StudyDefinition.time_limit_s`, of ``study.toml``'s template and of the simulated
study)."""

Task = Literal["pick_place", "pour"]
Interface = Literal["skin", "skin_registered", "keyboard", "pendant"]
Expertise = Literal["novice", "intermediate", "expert"]
Questionnaire = Literal["nasa_tlx", "sus"]
SimulatedHands = Literal["independent", "sim"]

TASKS: tuple[str, ...] = ("pick_place", "pour")
INTERFACES: tuple[str, ...] = ("skin", "skin_registered", "keyboard", "pendant")
EXPERTISE: tuple[str, ...] = ("novice", "intermediate", "expert")
HANDS_SOURCES: dict[str, str] = {
    "independent": "people and skins of wovenskin.independent, written apart from the "
    "simulator the recogniser was trained on",
    "sim": "people and skins of wovenskin.sim, the simulator the recogniser was trained on",
}
"""Whose people and skins a simulated study's operators touch the skin with, in words."""

# A participant id names a folder: letters, digits, '-' and '_' only.
_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")


def check_participant_id(value: str) -> str:
    """``value`` if it can name a participant's folder; :class:`ConfigError` otherwise."""
    if not _ID.fullmatch(value):
        raise ConfigError(
            f"bad participant id {value!r}: use 1-64 letters, digits, '-' or '_' "
            "(it names the participant's folder)"
        )
    return value


@dataclass(frozen=True)
class Participant:
    """One participant: an id (a folder name), an expertise level and free notes."""

    id: str
    expertise: Expertise
    notes: str = ""

    def __post_init__(self) -> None:
        check_participant_id(self.id)


@dataclass(frozen=True)
class StudyDefinition:
    """What a study runs: every participant does every task with every interface."""

    name: str
    tasks: tuple[Task, ...] = TASKS
    interfaces: tuple[Interface, ...] = ("skin", "keyboard", "pendant")
    trials_per_condition: Annotated[int, Ge(1)] = 3
    time_limit_s: Annotated[float, Gt(0)] = TIME_LIMIT_S
    questionnaires: tuple[Questionnaire, ...] = ()
    synthetic: bool = False  # set by `wovenskin study synthetic`: nothing in it was measured
    # set by `wovenskin study simulate`: simulated operators on the simulated arm and skin
    simulated: bool = False
    # set by `wovenskin study simulate`: whose people and skins its operators touched
    hands: SimulatedHands | None = None
    participants: tuple[Participant, ...] = ()

    def __post_init__(self) -> None:
        if not self.name.strip():
            raise ValueError("name: must not be empty")
        for key in ("tasks", "interfaces", "questionnaires"):
            values = getattr(self, key)
            if len(set(values)) != len(values):
                raise ValueError(f"{key}: each value once, got {list(values)}")
        if not self.tasks or not self.interfaces:
            raise ValueError("tasks and interfaces: at least one each")
        if self.hands is not None and not self.simulated:
            raise ValueError("hands: only a simulated study (simulated = true) has them")
        ids = [p.id for p in self.participants]
        if len(set(ids)) != len(ids):
            twice = sorted({i for i in ids if ids.count(i) > 1})
            raise ValueError(f"participants: id(s) {twice} given twice")

    def participant(self, participant_id: str) -> Participant:
        """The participant ``participant_id``; :class:`ConfigError` if the study has none."""
        for p in self.participants:
            if p.id == participant_id:
                return p
        raise ConfigError(f"no participant {participant_id!r} in study {self.name!r}")


def study_file(directory: str | Path) -> Path:
    return Path(directory) / STUDY_FILE


def parse_study(text: str, where: str = STUDY_FILE) -> StudyDefinition:
    """The study defined by the TOML ``text``; one :class:`ConfigError` line if it is bad."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML: {exc}") from None
    return from_dict(StudyDefinition, data, what=where)


def load_study(directory: str | Path) -> StudyDefinition:
    """Read ``DIR/study.toml``; a missing or bad file is one :class:`ConfigError` line."""
    path = study_file(directory)
    if Path(directory).exists() and not Path(directory).is_dir():
        raise ConfigError(f"{directory}: is a file, not a study folder")
    if not path.is_file():
        raise ConfigError(f"{path} not found: create a study with `wovenskin study init DIR`")
    return parse_study(path.read_text(encoding="utf-8"), str(path))


TEMPLATE = """\
# A wovenskin user study (docs/study.md). Every participant does every task with every
# interface; `wovenskin study plan DIR` orders them (balanced Latin squares).

name = "{name}"

# Tasks: "pick_place" (shapes into molds) and "pour" (particles from a cup).
tasks = ["pick_place", "pour"]

# Interfaces: "skin" (gestures, the paper's tool-frame mapping), "skin_registered"
# (gestures, skin-registered mapping), "keyboard", "pendant" (teach-pendant jog panel).
interfaces = ["skin", "keyboard", "pendant"]

# Trials of each task with each interface, and the time limit of one trial (seconds from
# the first command; a trial still running then ends as "timeout").
trials_per_condition = {trials_per_condition}
time_limit_s = {time_limit_s!r}

# Questionnaires after each interface: "nasa_tlx" (raw TLX) and/or "sus". [] for none.
questionnaires = ["nasa_tlx", "sus"]

# Participants, in the order they are run (the order picks their row of the Latin
# square). Add one with `wovenskin study add-participant DIR ID --expertise novice`.
# expertise: "novice", "intermediate" or "expert".
#
# [[participants]]
# id = "P01"
# expertise = "novice"
# notes = "right-handed"
"""


def init_study(directory: str | Path, name: str | None = None, overwrite: bool = False) -> Path:
    """Create ``DIR/study.toml`` from the commented template; returns its path."""
    folder = check_writable(directory, folder=True)
    folder.mkdir(parents=True, exist_ok=True)
    path = check_new_output(study_file(folder), overwrite, "a study definition")
    defaults = StudyDefinition(name="template")  # the template states the defaults
    text = TEMPLATE.format(
        name=_toml_text(name or folder.resolve().name),
        trials_per_condition=defaults.trials_per_condition,
        time_limit_s=defaults.time_limit_s,
    )
    parse_study(text)  # the template is always a valid study
    atomic_write_text(path, text)
    return path


def _toml_text(value: str) -> str:
    """``value`` as the inside of a TOML basic string."""
    escaped = value.replace("\\", "\\\\").replace('"', '\\"')
    return "".join(c if c.isprintable() else f"\\u{ord(c):04x}" for c in escaped)


def participant_block(participant: Participant) -> str:
    """The ``[[participants]]`` TOML table of ``participant``."""
    lines = [
        "[[participants]]",
        f'id = "{_toml_text(participant.id)}"',
        f'expertise = "{participant.expertise}"',
    ]
    if participant.notes:
        lines.append(f'notes = "{_toml_text(participant.notes)}"')
    return "\n".join(lines) + "\n"


def add_participant(
    directory: str | Path, participant_id: str, expertise: str, notes: str = ""
) -> StudyDefinition:
    """Append a participant to ``DIR/study.toml`` (its comments kept); the new study.

    The file is checked before and after: a duplicate id or a bad expertise leaves it as
    it was and raises one :class:`ConfigError` line.
    """
    path = study_file(directory)
    study = load_study(directory)
    participant = from_dict(
        Participant, {"id": participant_id, "expertise": expertise, "notes": notes}, "participant"
    )
    text = path.read_text(encoding="utf-8")
    if re.search(r"^\s*participants\s*=", text, flags=re.MULTILINE):
        raise ConfigError(
            f"{path} lists participants inline (participants = [...]); add the new one there"
        )
    if study.participants and any(p.id == participant.id for p in study.participants):
        raise ConfigError(f"participant {participant.id!r} is already in {path}")
    new_text = text.rstrip("\n") + "\n\n" + participant_block(participant)
    updated = parse_study(new_text, str(path))
    atomic_write_text(path, new_text)
    return updated
