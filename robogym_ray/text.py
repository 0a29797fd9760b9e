"""Bounded, one-line quoting of text that may come from outside: client-sent names, file
contents, remote tracebacks. Every error message and log line that repeats such text goes through
these, so a megabyte key or a multi-line traceback cannot flood a reply, a log or a terminal.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Collection, Iterable
from heapq import nsmallest

MAX_MESSAGE_CHARS = 2000
"""Longest error message put in a reply or a log line (robo-gym's client prints it whole)."""
MAX_REASON_CHARS = 500
"""Longest reason in a one-line reply (``reason``): enough for an option and the known ones."""
MAX_PREVIEW_ITEMS = 5
"""Client-sent names (unknown keys ...) quoted in one message; the rest are counted."""
MAX_PREVIEW_ITEM_CHARS = 80
"""Characters quoted of each of those names."""


def clip_text(text: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` on one line (no log-line injection), at most ``limit`` characters long."""
    if len(text) > limit:
        # Cut before anything else touches the text: it may be megabytes long.
        kept = max(0, limit - len(f"... [{len(text)} chars cut]"))
        text = f"{text[:kept]}... [{len(text) - kept} chars cut]"
    return text.replace("\r", " ").replace("\n", " ")


_ANSI_ESCAPE = re.compile(r"\x1b\[[0-9;?]*[ -/]*[@-~]")


def reason(text: str, limit: int = MAX_REASON_CHARS) -> str:
    """The first non-blank line of ``text``, ANSI colour codes removed, clipped to ``limit``.

    For replies to remote clients built from an exception that may carry a whole remote
    traceback (Ray's errors do, coloured, with paths, PIDs and IPs): the first line says what
    went wrong; the rest belongs in the log, not on the wire.
    """
    head = text[: 100 * limit]  # the first line is near the start; never scan megabytes
    lines = (line.strip() for line in _ANSI_ESCAPE.sub("", head).splitlines())
    return clip_text(next((line for line in lines if line), ""), limit)


def first_sentence(exc: BaseException, limit: int = 200) -> str:
    """The first sentence of an exception's first line, clipped to ``limit`` (library messages,
    torch's above all, run to paragraphs); its type's name when it has no message."""
    return reason(str(exc), limit).split(". ")[0] or type(exc).__name__


def preview(names: Collection[str]) -> str:
    """A bounded quote of client-sent names, the first few sorted: ``['a', 'b'] (+3 more)``."""
    shown = [quote(n) for n in nsmallest(MAX_PREVIEW_ITEMS, names)]
    more = len(names) - len(shown)
    return "[" + ", ".join(shown) + "]" + (f" (+{more} more)" if more else "")


def quote(name: str) -> str:
    """``repr(name)`` of at most MAX_PREVIEW_ITEM_CHARS characters of a client-sent name."""
    if len(name) <= MAX_PREVIEW_ITEM_CHARS:
        return repr(name)
    return f"{name[:MAX_PREVIEW_ITEM_CHARS]!r}... [{len(name) - MAX_PREVIEW_ITEM_CHARS} chars cut]"


MAX_SUGGESTED_CHARS = 200
"""Longest name compared for a suggestion: difflib's matching is quadratic in the length, and a
name that long is no misspelling of a short one."""


def did_you_mean(name: object, known: Iterable[str]) -> str:
    """``" (did you mean 'navigation'?)"`` for the entry of ``known`` closest to a misspelt
    ``name`` (by difflib's similarity ratio), or ``""`` when none is close.

    Put right after the unknown ``name`` in an error, before its list of choices.
    """
    if not isinstance(name, str) or not name or len(name) > MAX_SUGGESTED_CHARS:
        return ""
    candidates = list(known)
    close = difflib.get_close_matches(name, candidates, n=1, cutoff=0.6)
    if not close:  # a case slip ("UR10" for "ur10") scores low on the characters themselves
        folded = {c.lower(): c for c in candidates}
        close = [folded[m] for m in difflib.get_close_matches(name.lower(), folded, n=1)]
    return f" (did you mean {quote(close[0])}?)" if close else ""
