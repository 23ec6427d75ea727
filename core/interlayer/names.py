"""Names are data: the symbols a task planner sees for the names people give things.

A problem file may name a body ``left``, ``table 1``, ``On`` or ``(``: such names cannot all stand in a
PDDL formula, and they may clash with the domain's own objects (the robot's arms), PDDL's keywords, or
the references the core derives (``grasp_<object>``). Types, predicates and actions are names of other
kinds, and the task planner sees objects as ``o<k>`` anyway (interlayer_up.convert). A domain that
reads names from a user's file gives each one a safe, unique symbol here, once, when it builds its
problem, and uses the symbols everywhere inside (task model, geometry, plans). ``Problem.labels`` keeps
symbol -> name, and whatever a person reads (the plan, the trace's lines, ``check``, the pages, the
result's ``names``) shows the names again. A name that is already safe keeps itself as its symbol.
"""
from __future__ import annotations

import re

# PDDL's words that stand bare in formulas and declarations (the sectioning ones all start with ':'):
# a symbol equal to one of them could be misread by a task planner's parser
KEYWORDS = frozenset("""
and or not imply forall exists when either define object number at over start end all always sometime within
minimize maximize total-time total-cost increase decrease assign scale-up scale-down
""".split())
SAFE = re.compile(r"[A-Za-z][A-Za-z0-9_-]*")


class Names:
    """Allocates a safe, unique symbol per name; ``labels`` maps a symbol back to its name where the two
    differ (what ``Problem.labels`` wants).

    Symbols are PDDL names (a letter, then letters, digits, ``_`` and ``-``), unique, never one of
    ``reserved`` nor a PDDL keyword in any case, nor starting with one of ``prefixes`` (how the core
    names references: ``<skolem>_``). Case counts as it does for the task model."""

    def __init__(self, reserved=(), prefixes=()):
        self.labels: dict[str, str] = {}
        self._taken = set(reserved)
        self._prefixes = tuple(prefixes)

    @classmethod
    def for_domain(cls, domain, reserved=()) -> "Names":
        """Symbols that never read as one of ``domain``'s references (a DomainSpec's ``<skolem>_...``)."""
        return cls(reserved, [f"{s.name}_" for s in domain.skolems])

    def add(self, name: str, label: str | None = None) -> str:
        """A new symbol for ``name`` (its label, unless ``label`` is given): ``name`` itself when it is
        safe and free, else a cleaned form made unique. Two things of the same name get two symbols."""
        base = re.sub(r"[^A-Za-z0-9_-]+", "_", str(name)).strip("_-")
        if not base or not base[0].isalpha():
            base = f"n_{base}" if base else "n"
        symbol, k = base, 0
        while not self._free(symbol):
            k += 1
            symbol = f"n{k}_{base}" if self._prefixed(base) else f"{base}_{k}"
        self._taken.add(symbol)
        label = str(name) if label is None else label
        if label != symbol:
            self.labels[symbol] = label
        return symbol

    def label(self, symbol: str) -> str:
        return self.labels.get(symbol, symbol)

    def _prefixed(self, symbol: str) -> bool:
        return symbol.startswith(self._prefixes) if self._prefixes else False

    def _free(self, symbol: str) -> bool:
        return (bool(SAFE.fullmatch(symbol)) and symbol not in self._taken and symbol.lower() not in KEYWORDS
                and not self._prefixed(symbol))


def shown(labels, symbols) -> list:
    """``symbols`` (objects, references, arguments) as a person reads them."""
    return [labels.get(s, s) for s in symbols]


def step_text(step, labels=None) -> str:
    """A plan step (a GroundStep or its JSON dict) as a person reads it: ``pick(table 1, left, ...)``."""
    action, args = (step["action"], step["args"]) if isinstance(step, dict) else (step.action, step.args)
    return f"{action}({', '.join(shown(labels or {}, args))})"


def relabel(text: str, labels=None) -> str:
    """``text`` (a formula, fact, step or sentence as written) with every symbol replaced by its label:
    a symbol is a whole word of letters, digits, ``_`` and ``-``, and never a predicate, an action or a
    keyword."""
    if not labels:
        return text
    return re.sub(r"[A-Za-z0-9_-]+", lambda m: labels.get(m.group(0), m.group(0)), text)
