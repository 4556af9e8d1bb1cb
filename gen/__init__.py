"""kfgen.gen: the command line, parameter parsing, Verilog emission and reports."""

from importlib import metadata as _metadata

try:
    __version__ = _metadata.version("kfgen")
except _metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"
