"""Checks robot descriptions for ``interlayer robot check`` (hook ``interlayer_check_robot``)."""
from interlayer import hookimpl


@hookimpl
def interlayer_check_robot(path):
    from .check import robot_report

    return robot_report(path)
