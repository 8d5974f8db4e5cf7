"""The package's version, kept in a module of its own so that ``sweep --version`` and the
recordings' metadata read it without importing the engine."""
__version__ = "0.4.3"
