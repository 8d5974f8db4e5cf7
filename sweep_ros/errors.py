"""Errors of the node."""
from __future__ import annotations


class StartError(Exception):
    """The node cannot start: bad parameters or scene. ``problems``: one line each."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        super().__init__("; ".join(problems))
