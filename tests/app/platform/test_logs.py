"""Server log lines carry a UTC timestamp and a level, as text (the default) or as one JSON
object a line with ``ACV_LOG_FORMAT=json`` (issue 44 §5): the formatters on records, the
setting, and a fresh process configured as ``acv serve`` configures itself."""

from __future__ import annotations

import json
import logging
import re
import subprocess
import sys

import pytest
from pydantic import ValidationError

from app.core.logs import (
    ACCESS_TEXT,
    TEXT,
    AccessTextFormatter,
    JsonFormatter,
    TextFormatter,
    log_config,
)
from app.settings import Settings

#: A text line's start: the time in UTC to the millisecond, then uvicorn's padded level.
STAMP = r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z"
ACCESS_ARGS = ("127.0.0.1:50000", "GET", "/p/***", "1.1", 200)


def record(
    name: str, message: str, args: tuple = (), level: int = logging.INFO
) -> logging.LogRecord:
    return logging.LogRecord(name, level, __file__, 1, message, args, None)


def access_record() -> logging.LogRecord:
    return record("uvicorn.access", '%s - "%s %s HTTP/%s" %d', ACCESS_ARGS)


def test_a_text_line_starts_with_the_time_and_the_level() -> None:
    line = TextFormatter(fmt=TEXT, use_colors=False).format(record("app.x", "hello %s", ("you",)))
    assert re.fullmatch(rf"{STAMP} INFO: +hello you", line), line
    access = AccessTextFormatter(fmt=ACCESS_TEXT, use_colors=False).format(access_record())
    assert re.fullmatch(
        rf'{STAMP} INFO: +127\.0\.0\.1:50000 - "GET /p/\*\*\* HTTP/1\.1" 200 OK', access
    )


def test_a_json_line_names_the_time_level_logger_and_message() -> None:
    entry = json.loads(
        JsonFormatter().format(record("app.x", "hello %s", ("you",), logging.WARNING))
    )
    assert re.fullmatch(STAMP, entry.pop("time"))
    assert entry == {
        "level": "WARNING",
        "logger": "app.x",
        "message": "hello you",
        "process": entry["process"],
    }
    access = json.loads(JsonFormatter().format(access_record()))
    assert access["message"] == '127.0.0.1:50000 - "GET /p/*** HTTP/1.1" 200'
    assert [access[k] for k in ("client", "method", "path", "http_version", "status")] == list(
        ACCESS_ARGS
    )


def test_a_json_line_carries_the_traceback() -> None:
    try:
        raise ValueError("broken")
    except ValueError:
        failed = logging.LogRecord(
            "app.x", logging.ERROR, __file__, 1, "failed", (), sys.exc_info()
        )
    entry = json.loads(JsonFormatter().format(failed))
    assert entry["level"] == "ERROR" and "ValueError: broken" in entry["exception"]


def test_several_server_processes_name_theirs_in_text() -> None:
    formats = [f["fmt"] for f in log_config("text", workers=2)["formatters"].values()]
    assert all("[%(process)d]" in f and f.startswith("%(asctime)s") for f in formats)
    config = log_config("json", workers=2)
    assert {f["()"] for f in config["formatters"].values()} == {"app.core.logs.JsonFormatter"}
    assert config["loggers"]["app"]["level"] == "INFO" and config["root"]["level"] == "WARNING"


def test_the_setting_is_text_json_or_refused(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    assert Settings(data_dir=tmp_path).log_format == "text"
    monkeypatch.setenv("ACV_LOG_FORMAT", "json")
    assert Settings(data_dir=tmp_path).log_format == "json"
    with pytest.raises(ValidationError, match="log_format"):
        Settings(data_dir=tmp_path, log_format="xml")


CONFIGURED = """
import logging, sys
from app.core.logs import configure_logging
configure_logging(sys.argv[1])
logging.getLogger("app.jobs.worker").info("run %d claimed", 7)
logging.getLogger("uvicorn.error").info("Application startup complete.")
logging.getLogger("somelib").info("not shown: below the root's WARNING")
logging.getLogger("somelib").warning("disk %s", "full")
"""


@pytest.mark.process
@pytest.mark.parametrize("log_format", ["text", "json"])
def test_a_configured_process_stamps_every_line(log_format: str) -> None:
    done = subprocess.run(
        [sys.executable, "-c", CONFIGURED, log_format],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    lines = done.stderr.splitlines()
    assert len(lines) == 3, done.stderr
    if log_format == "text":
        assert re.fullmatch(rf"{STAMP} INFO: +run 7 claimed", lines[0])
        assert re.fullmatch(rf"{STAMP} INFO: +Application startup complete\.", lines[1])
        assert re.fullmatch(rf"{STAMP} WARNING: +disk full", lines[2])
    else:
        entries = [json.loads(line) for line in lines]
        assert [(e["level"], e["logger"], e["message"]) for e in entries] == [
            ("INFO", "app.jobs.worker", "run 7 claimed"),
            ("INFO", "uvicorn.error", "Application startup complete."),
            ("WARNING", "somelib", "disk full"),
        ]
        assert all(re.fullmatch(STAMP, e["time"]) for e in entries)
