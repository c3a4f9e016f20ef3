"""
What the trade-off results say.

The Pareto front of error against cost, and the cheapest method that reaches an error.
"""
from __future__ import annotations

import math


def pareto(rows: list[dict]) -> list[dict]:
    """Return the configurations no other beats in both cost and error."""
    ok = [r for r in rows if r['seconds_per_sim_second'] and math.isfinite(r['rel_l2'])]
    ok.sort(key=lambda r: (r['seconds_per_sim_second'], r['rel_l2']))
    front, best = [], math.inf
    for r in ok:
        if r['rel_l2'] < best:
            front.append(r)
            best = r['rel_l2']
    return front


def cheapest_reaching(rows: list[dict], error: float, methods) -> dict | None:
    ok = [r for r in rows if r['method'] in methods and r['seconds_per_sim_second']
          and r['rel_l2'] <= error]
    return min(ok, key=lambda r: r['seconds_per_sim_second']) if ok else None
