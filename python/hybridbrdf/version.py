"""The package's version (the same as pyproject.toml's, CMakeLists.txt's and version.hpp's; a test
checks them): recorded in every model file and training record."""

__version__ = "0.1.0"
