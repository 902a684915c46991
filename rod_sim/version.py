"""The version of rod_sim (``rod_sim.__version__``; setup.py and package.xml carry the same)."""

__version__ = "0.1.0"
