"""What the explorer's Bokeh server tells others about its errors: no traceback to a client, one line to its log.

A client that sends the server junk (a forged message, a closed socket) makes Bokeh and tornado log the
exception with its traceback, and reply with it: :func:`_no_tracebacks_to_clients` strips the reply's traceback,
:func:`one_line_logs` turns every such log record into one line (the exception's type and first line); a plugin's
own error keeps its traceback on the explorer's own logger, where a developer looks for it.
"""

from __future__ import annotations

import logging

#: The loggers whose records about a client's doing lose their traceback.
QUIET_LOGGERS = ("bokeh", "tornado.application", "tornado.general", "asyncio")


def _no_tracebacks_to_clients() -> None:
    """Make Bokeh's protocol ERROR replies carry no traceback (they reach whatever speaks to the socket)."""
    from bokeh.server.connection import ServerConnection

    if getattr(ServerConnection.error, "_brdflab", False):
        return

    def error(self, message, text: str):
        reply = self.protocol.create("ERROR", message.header["msgid"], "request refused")
        reply.content["traceback"] = None
        return reply

    error._brdflab = True
    ServerConnection.error = error


class _OneLine(logging.Filter):
    """Replace a record's traceback by the exception's type and first line."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and record.exc_info[1] is not None:
            exc = record.exc_info[1]
            first = (str(exc).strip().splitlines() or [""])[0][:200]
            record.msg = f"{record.getMessage()} ({type(exc).__name__}: {first})"
            record.args = ()
            record.exc_info = record.exc_text = None
        return True


def one_line_logs() -> None:
    """Install the one-line filter on :data:`QUIET_LOGGERS` and every logger below them that exists (a logger's
    filters do not see its children's records, and Bokeh's modules log on their own ``__name__`` loggers, all
    created when the server's modules are imported, before this is called)."""
    names = [n for n in logging.root.manager.loggerDict
             if any(n == q or n.startswith(q + ".") for q in QUIET_LOGGERS)]
    for name in dict.fromkeys([*QUIET_LOGGERS, *names]):
        logger = logging.getLogger(name)
        if not any(isinstance(f, _OneLine) for f in logger.filters):
            logger.addFilter(_OneLine())
