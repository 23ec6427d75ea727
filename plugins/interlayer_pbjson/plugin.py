"""Reads pybullet-planning JSON problem files (bodies / robots / task)."""
from interlayer import hookimpl


@hookimpl
def interlayer_load_problem(path, params, seed):
    """The problem of a pybullet-planning JSON file; None for anything else."""
    from .loader import load_pybullet_json, looks_like_pybullet_json

    data = looks_like_pybullet_json(path)
    if data is None:
        return None
    return load_pybullet_json(path, data, params, seed)
