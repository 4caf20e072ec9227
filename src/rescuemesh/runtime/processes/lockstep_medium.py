"""The radio medium of a world whose robots run in other processes: a frame that ends on the air is
handed to every robot that hears it at once, and the medium goes on when all have answered.

Owns: the order of one arrival's calls (every receiver's request sent, then every answer taken, then
each receiver's stack collected in the order the medium visited them). Must not know: Zenoh, how a
stand-in reaches its robot (runtime/processes/remote.py and process_world.py do), what a frame holds.

Why the run stays the same: in one process the medium calls receive(), then collects that stack
(its transmissions and timer), then goes to the next receiver. The receivers are distinct robots, so
one's receive() cannot change another's answer, and collecting them after all have received, in the
same order, makes the same heap pushes and the same draws. A stand-in in a batch sends its request
and answers False (the medium's "dropped, do not collect yet"); this class collects it afterwards.
"""

from __future__ import annotations

from typing import Protocol

from rescuemesh.transport.sim_medium import SimMedium


class Deliveries(Protocol):
    """Who sends the batched requests (ProcessRuntime): `begin()` opens a batch that the stand-ins'
    receive() join; `end()` sends it, waits for every answer, primes each stand-in with its answer and
    returns the stand-ins in the order they joined."""

    def begin(self) -> None: ...
    def end(self) -> list: ...


class LockstepMedium(SimMedium):
    """SimMedium whose arrivals go to all their receivers in one parallel round of requests."""

    deliveries: Deliveries | None = None

    def _arrive(self, burst, at: float) -> None:
        deliveries = self.deliveries
        if deliveries is None or self.observe is not None:
            super()._arrive(burst, at)
            return
        deliveries.begin()
        try:
            super()._arrive(burst, at)
        finally:
            stacks = deliveries.end()
        high = self.timing.response_delay_s[1]
        for stack in stacks:  # each with the response delay the medium drew for it in this arrival
            radio = self._radio(stack.address)
            respond_s = float(self._response_delay[radio.index]) if high > 0.0 else 0.0
            self._collect(radio, at, respond_s=respond_s)
