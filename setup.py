"""Package discovery that cannot forget a subpackage: every package under fusionkit/, and every
package under plugins/ installed as fusionkit_plugins. Everything else is in pyproject.toml."""

from setuptools import find_packages, setup

setup(packages=find_packages(include=["fusionkit", "fusionkit.*"])
      + ["fusionkit_plugins" + name[len("plugins"):] for name in find_packages(include=["plugins", "plugins.*"])])
