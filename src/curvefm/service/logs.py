"""The server's logging: uvicorn's configuration, with secrets redacted from every record before it is written.

uvicorn's access log prints each request line with its query string, and the login URL carries ``?token=`` (the
single sign-on's return, ``?code=...&state=...``); an exception's message might quote a header.
:class:`RedactSecrets` rewrites a record's message, arguments and traceback text: ``token=``, ``code=`` and
``state=`` query values, bearer credentials and anything shaped like one of our tokens.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import re

from curvefm.access import redact_tokens

_QUERY_TOKEN = re.compile(r"([?&](?:(?:access_)?token|code|state)=)[^&\s\"']*", re.IGNORECASE)
_BEARER = re.compile(r"(bearer\s+)[^\s\"',]+", re.IGNORECASE)
REDACTED = "[redacted]"
APP_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


def redact(text: str) -> str:
    text = _QUERY_TOKEN.sub(r"\1" + REDACTED, text)
    return redact_tokens(_BEARER.sub(r"\1" + REDACTED, text))


class RedactSecrets(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        if record.name == "uvicorn.access":  # its formatter reads the arguments by position
            record.args = tuple(redact(arg) if isinstance(arg, str) else arg for arg in record.args or ())
        else:
            with contextlib.suppress(TypeError, ValueError):  # a malformed call is logging's to report
                record.msg, record.args = redact(record.getMessage()), None
        if record.exc_info and not record.exc_text:
            record.exc_text = redact(logging.Formatter().formatException(record.exc_info))
        return True


def log_config(level: str) -> dict:
    """uvicorn's logging configuration plus a root handler for our own loggers, every handler redacting."""
    from uvicorn.config import LOGGING_CONFIG

    config = copy.deepcopy(LOGGING_CONFIG)
    config["filters"] = {"redact": {"()": RedactSecrets}}
    config["formatters"]["app"] = {"format": APP_FORMAT}
    config["handlers"]["app"] = {"formatter": "app", "class": "logging.StreamHandler", "stream": "ext://sys.stderr"}
    for handler in config["handlers"].values():
        handler["filters"] = ["redact"]
    config["root"] = {"handlers": ["app"], "level": level.upper()}
    return config
