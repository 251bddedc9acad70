"""Build hook (the project's metadata is in pyproject.toml): a wheel carries the repository's
``maps/``, ``configs/`` and ``checkpoints/`` as package data, ``aoass_env/_data/<folder>``,
where :func:`aoass_env.data.shipped_dir` finds them. An editable install uses the checkout's
folders and copies nothing."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

SHIPPED = ("maps", "configs", "checkpoints")
#: What a training run or a test leaves in those folders (.gitignore): never shipped.
LEFT_BY_RUNS = ("last.zip", "final.zip", "*_replay_buffer.pkl", "*.tmp", "__pycache__")


class BuildPyWithData(build_py):
    """``build_py`` that also copies the shipped folders into the built package."""

    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        root = Path(__file__).resolve().parent
        for name in SHIPPED:
            shutil.copytree(root / name, Path(self.build_lib) / "aoass_env" / "_data" / name,
                            ignore=shutil.ignore_patterns(*LEFT_BY_RUNS), dirs_exist_ok=True)


setup(cmdclass={"build_py": BuildPyWithData})
