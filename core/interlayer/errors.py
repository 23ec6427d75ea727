"""Errors a user can act on: each message is one plain sentence naming the thing and the fix."""


class UserError(Exception):
    """Bad input (config, problem file, plugin name). The CLI prints it and exits with code 2."""


class DomainError(UserError):
    """A domain declaration that cannot be abstracted (unknown predicate, type, malformed formula)."""


def closest(name: str, choices) -> str:
    """' (did you mean X?)' for the nearest valid name, or ''."""
    import difflib

    by_lower = {str(c).lower(): str(c) for c in choices}
    match = difflib.get_close_matches(str(name), [str(c) for c in choices], n=1)
    if not match:  # case differences count less than letters: IsGrasp -> IsGP
        match = [by_lower[m] for m in difflib.get_close_matches(str(name).lower(), by_lower, n=1)]
    return f" (did you mean '{match[0]}'?)" if match else ""
