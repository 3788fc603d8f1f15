"""Parameter changes take effect at once (in flight too): a table from parameter name to what it re-applies.

Each component's parameters are declared once in its ``param_decls`` (``autopilot.param_schema``); this module
only says which component re-reads which names. Reads the ``ParamStore``'s change notifications; calls the
bound handlers with ``(name, value)``; names bound to nothing change no state beyond the store.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from autopilot.params import ParamStore

Handler = Callable[[str, float], None]


class ParamBindings:
    """``name -> handlers``; subscribe it to a ``ParamStore`` (``ParamStore.subscribe``)."""

    def __init__(self) -> None:
        self._table: dict[str, list[Handler]] = {}
        self._every: list[Handler] = []

    def bind(self, names: Iterable[str], handler: Handler) -> None:
        """Call ``handler`` when any of ``names`` changes (in the order bound)."""
        for name in names:
            self._table.setdefault(name, []).append(handler)

    def bind_every(self, handler: Handler) -> None:
        """Call ``handler`` on every change, before the named handlers (cache invalidation)."""
        self._every.append(handler)

    def names(self) -> frozenset[str]:
        return frozenset(self._table)

    def __call__(self, name: str, value: float) -> None:
        for handler in self._every:
            handler(name, value)
        for handler in self._table.get(name, ()):
            handler(name, value)

    def attach(self, store: ParamStore) -> None:
        """Unknown names are refused at binding time: a typo cannot silently bind nothing."""
        unknown = sorted(name for name in self._table if name not in store)
        if unknown:
            raise ValueError(f"parameter bindings name undeclared parameters: {', '.join(unknown)}")
        store.subscribe(self)
