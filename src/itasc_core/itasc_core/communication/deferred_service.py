"""Services whose answer comes later (paper §6.1 pure coordination; §7.2 service calls).

An operator's ``~/recover`` can only be answered once the Coordinator heard back from the
entities it asked (by events) and saw its composite reach Running. A Coordinator must never block
in a callback (it is a pure event processor), and rclpy's EventsExecutor takes no coroutine as a
service callback. So a callback may return :class:`Later` instead of a response: the request is
kept with the caller's header, and :meth:`Later.answer` sends the response from any later callback
of the same executor.
"""

from __future__ import annotations

import types
from typing import Any, Callable

from rclpy.node import Node
from rclpy.service import Service

__all__ = ['Later', 'create_deferred_service']


class Later:
    """A request answered later: ``answer(response)`` sends it to the caller (once)."""

    def __init__(self, service: Service) -> None:
        self._service = service
        self._header: Any = None
        self._response: Any = None

    def answer(self, response: Any) -> None:
        if self._response is not None:
            return
        self._response = response
        if self._header is not None:
            Service.send_response(self._service, response, self._header)

    def _taken(self, header: Any) -> None:
        """The executor hands over the caller's header (right after the callback returned)."""
        self._header = header
        if self._response is not None:  # answered before the callback even returned
            Service.send_response(self._service, self._response, header)


def create_deferred_service(node: Node, srv_type: Any, name: str,
                            callback: Callable[[Any, Any, Later], Any]) -> Service:
    """A service of ``node`` whose ``callback(request, response, later)`` returns either the
    response or ``later`` (then answered with ``later.answer(response)``)."""
    service: Service

    def on_request(request: Any, response: Any) -> Any:
        return callback(request, response, Later(service))

    def send_response(self: Service, response: Any, header: Any) -> None:
        if isinstance(response, Later):
            response._taken(header)
        else:
            Service.send_response(self, response, header)

    service = node.create_service(srv_type, name, on_request)
    service.send_response = types.MethodType(send_response, service)  # type: ignore[method-assign]
    return service
