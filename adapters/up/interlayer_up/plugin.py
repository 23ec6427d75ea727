"""Registers Unified-Planning engines as task planners (import-light: UP loads on first use)."""
import importlib.util

from interlayer import hookimpl

ENGINES = {
    "fast-downward": ("up_fast_downward", "Fast Downward, lama-first (satisficing)", {}),
    "fast-downward-opt": ("up_fast_downward", "Fast Downward A* + LM-cut (cost-optimal)", {}),
    "fast-downward-bjolp": ("up_fast_downward", "Fast Downward seq-opt-bjolp: A* + landmarks (cost-optimal; "
                            "scales best on Dinner-N)", {"fast_downward_alias": "seq-opt-bjolp"}),
    "ff": ("up_fast_downward", "FF's algorithm in Fast Downward: EHC + FF heuristic + helpful actions, GBFS fallback", None),
    "pyperplan": ("up_pyperplan", "pyperplan (pure Python, STRIPS after UP compilation; small problems)", {}),
    "enhsp": ("up_enhsp", "ENHSP", {}),
    "symk-opt": ("up_symk", "SymK (cost-optimal symbolic search; pip install 'interlayer[symk]')", {}),
}


def _factory(name, default_params):
    def make(options):
        from interlayer.errors import UserError

        from .planner import FF_SEARCHES, UPTaskPlanner

        opts = dict(options)
        validate = opts.pop("validate", "off")
        if validate not in ("every", "final", "off"):
            raise UserError(f"task_planner.{name}.validate must be 'every', 'final' or 'off', got {validate!r}.")
        warm = opts.pop("warm", True)
        if not isinstance(warm, bool):
            raise UserError(f"task_planner.{name}.warm must be true or false, got {warm!r}.")
        fallbacks = ()
        if name == "ff":
            engine, params = "fast-downward", {"fast_downward_search_config": FF_SEARCHES[0]}
            fallbacks = ({"fast_downward_search_config": FF_SEARCHES[1]},)
        elif name == "fast-downward-bjolp":  # an alias of the satisficing engine name (seq-opt-bjolp scaled best on Dinner-N)
            engine, params = "fast-downward", dict(default_params)
        else:
            engine, params = name, dict(default_params or {})
        if "search" in opts:  # any Fast Downward search string
            params, fallbacks = {"fast_downward_search_config": opts.pop("search")}, ()
        if "alias" in opts:
            params = {"fast_downward_alias": opts.pop("alias")}
        params.update(opts.pop("params", {}))
        if opts:
            raise UserError(f"Unknown option(s) {sorted(opts)} for task planner '{name}'; valid: search, alias, params, validate, warm.")
        return UPTaskPlanner(name=name, engine=engine, params=params, fallbacks=fallbacks, validate=validate, warm=warm)

    return make


@hookimpl
def interlayer_register_task_planners(registry):
    for name, (module, description, params) in ENGINES.items():
        if importlib.util.find_spec(module) is None:
            registry.unavailable(name, f"the Python package '{module}' is not installed", description)
        else:
            registry.add(name, _factory(name, params), description)
