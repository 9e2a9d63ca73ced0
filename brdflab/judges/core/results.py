"""Behaviour shared by the result objects that hold one entry per case (angles, extreme cases)."""

from __future__ import annotations

from typing import ClassVar


class CaseList:
    """Iterable, sized, indexable over the list attribute named by :attr:`cases_attr`; ``passed`` when that
    list is non-empty and every entry passed (a check with no cases never passes)."""

    cases_attr: ClassVar[str] = ""

    def _cases(self) -> list:
        return getattr(self, self.cases_attr)

    @property
    def passed(self) -> bool:
        """Every case passed (and there was at least one)."""
        cases = self._cases()
        return bool(cases) and all(c.passed for c in cases)

    def __iter__(self):
        return iter(self._cases())

    def __len__(self) -> int:
        return len(self._cases())

    def __getitem__(self, i):
        return self._cases()[i]
