"""The names downloads are saved under: ``<session>_<converter>_r<revision>_<file>``, so that the files of different
sessions, converters and revisions never overwrite each other in a Downloads folder. The session is its name made
filename-safe, then its id (names repeat: every session of a pair is called "source -> target" by default); a live
export's converter is ``live``. The files on disk keep their plain names (``maps.mat``): stored jobs link to those."""

from __future__ import annotations

import re

LIVE = "live"
"""The converter part of a live export's name: the session's maps as they are, not a refinement's."""
_UNSAFE = re.compile(r"[^A-Za-z0-9._]+")
MAX_NAME_PART = 60


def filename_safe(text: str) -> str:
    """``text`` with every run of characters other than ASCII letters, digits, ``.`` and ``_`` made one ``-``
    (no leading or trailing ``-`` or ``.``), at most :data:`MAX_NAME_PART` characters: ``cat -> lion`` is
    ``cat-lion``."""
    return _UNSAFE.sub("-", text).strip("-.")[:MAX_NAME_PART].strip("-.")


def download_name(session_id: str, session_name: str, converter: str, revision: int, file: str) -> str:
    """``<name>_<id>_<converter>_r<revision>_<file>`` (``<id>_...`` for a session without a name)."""
    name = filename_safe(session_name)
    session = f"{name}_{session_id}" if name else session_id
    return f"{session}_{filename_safe(converter)}_r{revision}_{file}"


def attachment(filename: str) -> dict[str, str]:
    """The Content-Disposition header that saves a download as ``filename`` (ASCII: :func:`download_name`'s)."""
    return {"Content-Disposition": f'attachment; filename="{filename}"'}
