"""Server log lines: every line of uvicorn's loggers, the app's own and any library's warning
carries a UTC timestamp and a level, as text (the default) or as one JSON object a line
(``ACV_LOG_FORMAT=json``, for log collectors).

Text keeps uvicorn's look with the time in front::

    2026-11-27T17:42:00.123Z INFO:     Application startup complete.
    2026-11-27T17:42:01.456Z INFO:     127.0.0.1:50000 - "GET /login HTTP/1.1" 200

JSON names the same things, and a request's parts apart::

    {"time": "2026-11-27T17:42:01.456Z", "level": "INFO", "logger": "uvicorn.access",
     "message": "127.0.0.1:50000 - \\"GET /login HTTP/1.1\\" 200", "process": 4242,
     "client": "127.0.0.1:50000", "method": "GET", "path": "/login", "status": 200}

The lines that ``acv serve`` prints before serving (the login link) are output, not log.
"""

from __future__ import annotations

import copy
import json
import logging
import logging.config
from datetime import UTC, datetime
from typing import Any

import uvicorn.config
from uvicorn.logging import AccessFormatter, DefaultFormatter

from app.settings import LogFormat

#: uvicorn's formats, with the time in front.
TEXT = "%(asctime)s %(levelprefix)s %(message)s"
ACCESS_TEXT = '%(asctime)s %(levelprefix)s %(client_addr)s - "%(request_line)s" %(status_code)s'
#: The loggers of our own code; anything else reaches the root logger (warnings and up).
OWN_LOGGERS = ("app", "engine")
#: The arguments of uvicorn's access records, in order.
ACCESS_FIELDS = ("client", "method", "path", "http_version", "status")


def utc_time(created: float) -> str:
    """A record's time as ISO 8601 in UTC, to the millisecond: ``2026-11-27T17:42:00.123Z``."""
    moment = datetime.fromtimestamp(created, UTC).isoformat(timespec="milliseconds")
    return moment.replace("+00:00", "Z")


class TextFormatter(DefaultFormatter):
    """uvicorn's formatter (its padded, coloured level), with :func:`utc_time`."""

    def formatTime(self, record: logging.LogRecord, datefmt: str | None = None) -> str:
        return utc_time(record.created)


class AccessTextFormatter(AccessFormatter):
    """uvicorn's access-line formatter, with :func:`utc_time`."""

    def formatTime(self, record: logging.LogRecord, datefmt: str | None = None) -> str:
        return utc_time(record.created)


class JsonFormatter(logging.Formatter):
    """One JSON object a line: ``time``, ``level``, ``logger``, ``message``, ``process``;
    ``exception`` with a traceback; a request's ``client``, ``method``, ``path``,
    ``http_version`` and ``status`` for uvicorn's access lines (the path as
    :mod:`app.http.access_log` masked it).

    Args:
        use_colors: ignored (uvicorn passes it to every formatter when told to colour).
    """

    def __init__(self, use_colors: bool | None = None) -> None:
        super().__init__()

    def format(self, record: logging.LogRecord) -> str:
        entry: dict[str, Any] = {
            "time": utc_time(record.created),
            "level": record.levelname,
            "logger": record.name,
            "message": record.getMessage(),
            "process": record.process,
        }
        args = record.args
        if record.name == "uvicorn.access" and isinstance(args, tuple) and len(args) == 5:
            entry |= dict(zip(ACCESS_FIELDS, args, strict=True))
        if record.exc_info:
            entry["exception"] = self.formatException(record.exc_info)
        return json.dumps(entry, default=str)


def log_config(log_format: LogFormat = "text", workers: int = 1) -> dict[str, Any]:
    """The :func:`logging.config.dictConfig` of a server process: uvicorn's loggers, ours at
    INFO, and the root logger's warnings, in ``log_format``; with several server processes
    every text line names its process id (a JSON line always does)."""
    config = copy.deepcopy(uvicorn.config.LOGGING_CONFIG)
    formatters = config["formatters"]
    if log_format == "json":
        for name in formatters:
            formatters[name] = {"()": f"{__name__}.JsonFormatter"}
    else:
        formatters["default"] |= {"()": f"{__name__}.TextFormatter", "fmt": TEXT}
        formatters["access"] |= {"()": f"{__name__}.AccessTextFormatter", "fmt": ACCESS_TEXT}
        if workers > 1:
            for formatter in formatters.values():
                formatter["fmt"] = formatter["fmt"].replace(
                    "%(levelprefix)s", "%(levelprefix)s [%(process)d]"
                )
    for name in OWN_LOGGERS:
        config["loggers"][name] = {"handlers": ["default"], "level": "INFO", "propagate": False}
    config["root"] = {"handlers": ["default"], "level": "WARNING"}
    return config


def configure_logging(log_format: LogFormat = "text", workers: int = 1) -> None:
    """Apply :func:`log_config` to this process (a server, ``acv worker``, a backfill)."""
    logging.config.dictConfig(log_config(log_format, workers))
