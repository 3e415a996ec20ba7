"""Slow clients: a connection must send its first request's headers within ``header_timeout_s`` (uvicorn waits for
ever; later requests on a kept-alive connection have its keep-alive timeout), and a request body must keep
arriving, each read within ``body_timeout_s`` (408 otherwise)."""

from __future__ import annotations

import asyncio

import anyio
import h11
from fastapi import HTTPException
from uvicorn.protocols.http.h11_impl import H11Protocol

from curvefm.service.settings import env_name


def timed_h11(header_timeout_s: float) -> type[H11Protocol]:
    """uvicorn's h11 protocol with a deadline on every request's headers: ``header_timeout_s`` from the
    connection's start, or from the first bytes of a later request on a kept-alive connection (uvicorn's own
    keep-alive timer stops at the first byte, so a client trickling its headers was kept for ever)."""

    class TimedH11Protocol(H11Protocol):
        headers_due: asyncio.TimerHandle | None = None

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self.headers_due = self.loop.call_later(header_timeout_s, self.timeout_keep_alive_handler)

        def data_received(self, data: bytes) -> None:
            if self.headers_due is None and self.conn.their_state is h11.IDLE:
                self.headers_due = self.loop.call_later(header_timeout_s, self.timeout_keep_alive_handler)
            super().data_received(data)
            if self.headers_due is not None and self.conn.their_state is not h11.IDLE:  # the headers are in
                self.headers_due.cancel()
                self.headers_due = None

        def connection_lost(self, exc: Exception | None) -> None:
            if self.headers_due is not None:
                self.headers_due.cancel()
            super().connection_lost(exc)

    return TimedH11Protocol


class BodyTimeout(HTTPException):
    """A request body that stopped arriving (raised by the timed ``receive``; answered 408 as an ErrorBody)."""

    def __init__(self, timeout_s: float):
        super().__init__(
            status_code=408,
            detail=f"the request body stopped arriving: nothing came for {timeout_s:g} s (set "
            f"{env_name('body_timeout_s')} to change it)",
        )


def timed_receive(receive, timeout_s: float):
    """``receive`` that raises :class:`BodyTimeout` when one read of the body waits more than ``timeout_s``."""

    async def receive_in_time():
        try:
            with anyio.fail_after(timeout_s):
                return await receive()
        except TimeoutError:
            raise BodyTimeout(timeout_s) from None

    return receive_in_time
