"""Limits of differential IK, one class per file (see [`optik.diffik.Limit`][optik.diffik.Limit])."""

from optik.diffik.limits.acceleration import AccelerationLimit
from optik.diffik.limits.closure import ClosureConstraint
from optik.diffik.limits.configuration import ConfigurationLimit
from optik.diffik.limits.velocity import VelocityLimit

__all__ = ["AccelerationLimit", "ClosureConstraint", "ConfigurationLimit", "VelocityLimit"]
