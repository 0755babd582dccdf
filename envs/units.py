"""Named unit conversions used at the edges (configs, sensors, reports). Inside: SI and radians."""

import math

DEG_PER_RAD = 180.0 / math.pi


def deg_to_rad(x: float) -> float:
    """Degrees -> radians."""
    return x / DEG_PER_RAD


def rad_to_deg(x: float) -> float:
    """Radians -> degrees."""
    return x * DEG_PER_RAD


def per_deg_to_per_rad(x: float) -> float:
    """A coefficient per degree (e.g. N·m/deg, N·m·s/deg, N·m·s²/deg) -> per radian."""
    return x * DEG_PER_RAD


def per_rad_to_per_deg(x: float) -> float:
    """A coefficient per radian -> per degree."""
    return x / DEG_PER_RAD


def rad_per_count(counts_per_rev: float) -> float:
    """Encoder resolution in rad for an encoder with counts_per_rev counts per revolution."""
    return 2.0 * math.pi / counts_per_rev


def counts_to_rad(counts: float, counts_per_rev: float) -> float:
    """Encoder counts -> radians."""
    return counts * rad_per_count(counts_per_rev)


def rad_to_counts(theta: float, counts_per_rev: float) -> float:
    """Radians -> (fractional) encoder counts."""
    return theta / rad_per_count(counts_per_rev)
