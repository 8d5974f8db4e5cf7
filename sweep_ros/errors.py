"""Errors of the node."""
from __future__ import annotations


class StartError(Exception):
    """The node cannot start: bad parameters or scene. ``problems``: one line each."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        super().__init__("; ".join(problems))

    def __reduce__(self) -> tuple:
        """Pickled with its argument (the list of problems, not their joined line)."""
        return (type(self), (self.problems,), self.__dict__)
