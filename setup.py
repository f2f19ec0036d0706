"""Packages and package data, found so that none is forgotten: every package under fusionkit/; every
package under plugins/, installed as fusionkit_plugins; and the robot descriptions shipped with fusionkit,
robots/<family>/*.yaml (and URDFs beside them), installed as the data package fusionkit_robots, which each
family registers its own folder of. A family folder has no __init__.py but Python can import it (a namespace
package), so it is declared a package of its own, its files its data: left out of `packages`, setuptools
warns about it. Everything else is in pyproject.toml."""

from pathlib import Path

from setuptools import find_packages, setup

ROOT = Path(__file__).resolve().parent
plugins = ["fusionkit_plugins" + name[len("plugins"):] for name in find_packages(include=["plugins", "plugins.*"])]
robots = ["fusionkit_robots"] + [f"fusionkit_robots.{p.name}" for p in sorted(ROOT.joinpath("robots").iterdir())
                                 if p.is_dir() and p.name.isidentifier()]

setup(packages=find_packages(include=["fusionkit", "fusionkit.*"]) + plugins + robots,
      package_dir={"fusionkit_plugins": "plugins", "fusionkit_robots": "robots"},
      package_data={name: ["*.yaml", "*.urdf"] for name in robots[1:]})
