"""Errors the library raises for bad input: one clear line each."""

from __future__ import annotations

__all__ = ["InputError", "SkyMapError", "PlanCheckError"]


class InputError(ValueError):
    """Bad input from the user or an upstream message; the text says what."""


class SkyMapError(InputError):
    """A sky map that cannot be read or is not a probability map."""


class PlanCheckError(RuntimeError):
    """A plan failed the independent plan checker (a scheduler bug)."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        head = problems[0] if problems else "unknown problem"
        more = f" (+{len(problems) - 1} more)" if len(problems) > 1 else ""
        super().__init__(f"plan failed the checker: {head}{more}")
