"""Packages and package data, found so that none is forgotten: every package under fusionkit/; every
package under plugins/, installed as fusionkit_plugins; and each plugin family's robot descriptions
(plugins/<family>/robots/*.yaml). A `robots/` folder has no __init__.py but Python can import it (a
namespace package), so it is declared a package of its own, its .yaml files its data: left out of
`packages`, setuptools warns about it (some 40 lines per family). Everything else is in pyproject.toml."""

from pathlib import Path

from setuptools import find_packages, setup

ROOT = Path(__file__).resolve().parent
plugins = ["fusionkit_plugins" + name[len("plugins"):] for name in find_packages(include=["plugins", "plugins.*"])]
robots = [f"{name}.robots" for name in plugins if (ROOT.joinpath("plugins", *name.split(".")[1:], "robots")).is_dir()]

setup(packages=find_packages(include=["fusionkit", "fusionkit.*"]) + plugins + robots,
      package_dir={"fusionkit_plugins": "plugins"},
      package_data={name: ["*.yaml", "*.urdf"] for name in robots})
