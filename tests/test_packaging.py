"""pyproject's version floors and ``constraints-lowest.txt`` cannot drift apart.

CI (``.ci/run``) installs ``-c constraints-lowest.txt -e ".[test]"`` into a fresh virtual
environment and runs a smoke subset there, so every floor declared in pyproject is a floor that
was tested. That holds only while the constraints file pins each floor exactly: these tests parse
both files and fail on a floor that is missing, unpinned or pinned at another version.
"""

from __future__ import annotations

import importlib
import warnings
from importlib.metadata import version as installed_version
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

try:
    import tomllib
except ModuleNotFoundError:                 # Python 3.10: tomllib is 3.11's
    tomllib = pytest.importorskip("tomli")

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = ROOT / "pyproject.toml"
LOWEST = ROOT / "constraints-lowest.txt"

# The one documented exception: torch's floor cannot be installed on the project's machines,
# which carry only a local CPU wheel, so the lowest environment pins that wheel instead.
NOT_AT_FLOOR = {"torch": Version("2.13.0")}

# The module each distribution is imported as, where the two names differ.
MODULES = {"pyyaml": "yaml", "scikit-fuzzy": "skfuzzy", "stable-baselines3": "stable_baselines3",
           "sb3-contrib": "sb3_contrib", "pytest-xdist": "xdist"}


def _requirements() -> list[Requirement]:
    """The runtime dependencies and the ``test`` extra: what the lowest environment installs."""
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    return [Requirement(text)
            for text in project["dependencies"] + project["optional-dependencies"]["test"]]


def _floor(requirement: Requirement) -> Version | None:
    floors = [Version(spec.version) for spec in requirement.specifier if spec.operator == ">="]
    return max(floors) if floors else None


def _pins() -> dict[str, Version]:
    """``name==version`` lines of constraints-lowest.txt (comments and blank lines skipped)."""
    pins: dict[str, Version] = {}
    for number, line in enumerate(LOWEST.read_text().splitlines(), 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        requirement = Requirement(text)
        specs = list(requirement.specifier)
        assert len(specs) == 1 and specs[0].operator == "==", \
            f"constraints-lowest.txt line {number}: expected name==version, got {text!r}"
        name = canonicalize_name(requirement.name)
        assert name not in pins, f"constraints-lowest.txt line {number}: {name} pinned twice"
        pins[name] = Version(specs[0].version)
    return pins


@pytest.mark.parametrize("requirement", _requirements(), ids=lambda r: r.name)
def test_every_floor_is_pinned_in_constraints_lowest(requirement: Requirement):
    name = canonicalize_name(requirement.name)
    floor = _floor(requirement)
    assert floor is not None, f"pyproject: {requirement} declares no >= floor"
    pins = _pins()
    assert name in pins, f"constraints-lowest.txt does not pin {name} (pyproject: >={floor})"
    expected = NOT_AT_FLOOR.get(name, floor)
    assert pins[name] == expected, \
        f"constraints-lowest.txt pins {name}=={pins[name]}, pyproject's floor is {floor}" + (
            f" (documented exception: pinned at {expected})" if name in NOT_AT_FLOOR else "")


def test_documented_exceptions_stay_above_their_floor():
    floors = {canonicalize_name(r.name): _floor(r) for r in _requirements()}
    for name, pinned in NOT_AT_FLOOR.items():
        assert name in floors and pinned >= floors[name]


@pytest.mark.parametrize("requirement", _requirements(), ids=lambda r: r.name)
def test_every_dependency_imports_at_a_version_within_its_range(requirement: Requirement):
    """Installed (at the floors in the lowest environment) and importable."""
    name = canonicalize_name(requirement.name)
    have = Version(installed_version(name))
    assert requirement.specifier.contains(have, prereleases=True), \
        f"{name} {have} is installed, pyproject asks for {requirement.specifier}"
    importlib.import_module(MODULES.get(name, name))


def test_sb3_progress_bar_dependencies_work():
    """``train.py`` shows SB3's progress bar, which draws with tqdm's rich front end."""
    from stable_baselines3.common.callbacks import ProgressBarCallback
    from tqdm.rich import tqdm

    ProgressBarCallback()                   # raises ImportError without tqdm and rich
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # tqdm marks its rich front end experimental
        assert sum(tqdm(range(3))) == 3
