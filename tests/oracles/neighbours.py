"""Oracle of the neighbour table's next deadline (mesh/neighbours.py): the scan of every entry it
was before the deadlines moved into a lazily cleaned heap."""

from __future__ import annotations


def next_deadline(table) -> float | None:
    """Earliest time at which an entry of `table` is lost (alive) or forgotten (lost), or None."""
    lost_s, expiry_s = table._lost_s, table._expiry_s
    return min((row.last_heard_s + (expiry_s if row.lost else lost_s) for row in table.snapshot()), default=None)
