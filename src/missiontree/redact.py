r"""Secrets out of every output, and terminal text without control sequences.

**Secrets.** A model provider registers the secrets it holds (:func:`register_secret`: its API
key, the password of a ``base_url``); :func:`scrub` then replaces any trace of them in a text with
``***``. A model or a server can hand a key back in many forms, so a trace is found in all of these:

- the key whole or any run of it of :data:`MIN_RUN` characters or more;
- split into pieces by spaces, punctuation or line breaks (``sk-ab cd12 ef...``), however short;
- upper- or lower-cased (matching ignores case);
- reversed;
- base64-encoded (standard or URL-safe, at any byte offset inside a longer base64 text) or in hex;
- partly altered or masked: a stretch that follows the key with at most :data:`MAX_GAP` wrong
  or starred (``*``) characters in a row counts when :data:`MIN_RUN` of its characters match;
- a single word of :data:`MIN_WORD` characters or more that is a piece of the key.

Only letters and digits are compared (the key's own ``-`` and ``_`` and any separators are left
out), so ``sk-test ok`` (six characters in common with a key ``sk-test-...``) stays text.

Outputs call :func:`scrub` (texts) or :func:`scrub_data` (JSON-ready data): the provider's answers
and errors, the tick log's lines, ``summary.json``, and the terminal (:class:`SafeTerminal`).

**Terminal text.** Ids, labels and answers from scene graphs and models may hold escape sequences
(set the window title, clear the screen). :func:`terminal_safe` shows every control character as a
visible escape (``\x1b``) instead, except newline, tab and carriage return.

**URLs.** :func:`redact_url` drops the user name and password of a URL and the values of its query.
"""

from __future__ import annotations

import base64
import re
import threading
from collections.abc import Iterable
from typing import Any, TextIO
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

#: Characters following the key (in order, separators left out) that make a trace of it.
MIN_RUN = 8
#: A word of this many letters and digits that is a piece of the key is a trace on its own.
MIN_WORD = 7
#: Wrong characters in a row a trace may hold (a masked or altered character is one).
MAX_GAP = 2
#: Where a trace is first looked for: three characters of the key in a row, or three at every
#: other place (a key with every second character masked); each hit is then followed.
_SEED_STEPS = (1, 2)
_SEED_LENGTH = 3
#: Secrets shorter than this (letters and digits) are not registered: they would match common text.
_SHORTEST = 6

_ALNUM = re.compile(r"[A-Za-z0-9]+")
#: What a text is compared by: letters, digits and mask stars (a star keeps the alignment, matches nothing).
_KEPT = re.compile(r"[A-Za-z0-9*]+")
_lock = threading.Lock()
#: A secret was registered (long or short): outputs are scrubbed from then on.
_active = False
#: The user name and password part of a URL (``scheme://user:password@``), replaced whatever it holds.
_USERINFO = re.compile(r"(?i)\b([a-z][a-z0-9+.-]*://)[^/\s@'\"<>]+@")
_secrets: set[str] = set()
_forms: list[str] = []
_seeds: tuple[dict[str, list[tuple[int, int]]], ...] = ({}, {})  # one for each of _SEED_STEPS


def register_secret(secret: str | None) -> None:
    """Scrub ``secret`` (and every form of it listed in the module docstring) from now on.

    A secret shorter than six letters and digits is not looked for in text (it would match common
    words); it is still hidden in URLs, whose user name and password are always scrubbed.
    """
    global _active
    if not secret:
        return
    _active = True
    if secret in _secrets or len(_compact(secret)) < _SHORTEST:
        return
    with _lock:
        _secrets.add(secret)
        for form in _forms_of(secret):
            if len(form) < _SHORTEST or form in _forms:
                continue
            index = len(_forms)
            _forms.append(form)
            for step, seeds in zip(_SEED_STEPS, _seeds, strict=True):
                reach = step * (_SEED_LENGTH - 1) + 1
                for start in range(len(form) - reach + 1):
                    seeds.setdefault(form[start:start + reach:step], []).append((index, start))


def forget_secrets() -> None:
    """Forget every registered secret (tests start from a clean state)."""
    global _active
    _active = False
    with _lock:
        _secrets.clear()
        _forms.clear()
        for seeds in _seeds:
            seeds.clear()


def has_secrets() -> bool:
    """True when a secret is registered (outputs can skip scrubbing otherwise)."""
    return _active


def scrub(text: str) -> str:
    """``text`` with every trace of a registered secret, and every URL's credentials, as ``***``."""
    if not _active or not text:
        return text
    text = _USERINFO.sub(r"\1***@", text)
    if not _forms:
        return text
    spans = _trace_spans(text)
    if not spans:
        return text
    out: list[str] = []
    last = 0
    for start, end in spans:
        out.append(text[last:start])
        out.append("***")
        last = end
    out.append(text[last:])
    return "".join(out)


def scrub_data(data: Any) -> Any:
    """``data`` (JSON-ready: dicts, lists, strings, numbers) with every string scrubbed."""
    if not _active:
        return data
    if isinstance(data, str):
        return scrub(data)
    if isinstance(data, dict):
        return {scrub(k) if isinstance(k, str) else k: scrub_data(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [scrub_data(v) for v in data]
    return data


def redact_url(url: str) -> str:
    """``url`` without its user name and password (``***@``) and with its query values as ``***``."""
    try:
        parts = urlsplit(url)
        host = parts.hostname or ""
        port = f":{parts.port}" if parts.port is not None else ""
    except ValueError:
        return "<a URL that cannot be read>"
    netloc = parts.netloc
    if "@" in netloc:
        netloc = f"***@{host}{port}"
    query = parts.query
    if query:
        query = urlencode([(k, "***") for k, _ in parse_qsl(query, keep_blank_values=True)], safe="*")
    return urlunsplit((parts.scheme, netloc, parts.path, query, ""))


def url_secrets(url: str | None) -> list[str]:
    """The secrets a URL holds: its password, user name and query values (to register)."""
    if not url:
        return []
    try:
        parts = urlsplit(url)
        found = [parts.password or "", parts.username or ""]
    except ValueError:
        return []
    found += [v for _, v in parse_qsl(parts.query, keep_blank_values=True)]
    return [s for s in found if s]


_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def terminal_safe(text: str) -> str:
    r"""``text`` with control characters (escape sequences, bidi overrides) shown as ``\xNN`` escapes."""
    return _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)


class SafeTerminal:
    r"""A text stream for the terminal: scrubs secrets and shows foreign control characters escaped.

    Wraps ``sys.stdout``/``sys.stderr`` for a command's run (:mod:`missiontree.cli.main`). Text is
    passed on a line at a time (up to a newline, a carriage return or the erase-line sequence, or
    at :meth:`flush`), so a secret written in several pieces (``json.dump`` writes token by token)
    is scrubbed whole. The progress lines' own ``\r`` and erase-line sequence pass.
    """

    _OWN = "\x1b[K"
    _ENDS = re.compile(r"\n|\r|\x1b\[K")

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream
        self._pending = ""

    def write(self, text: str) -> int:
        """Take ``text``; pass on every whole line made safe; return the length of ``text``."""
        self._pending += text
        ends = [match.end() for match in self._ENDS.finditer(self._pending)]
        if ends:
            ready, self._pending = self._pending[:ends[-1]], self._pending[ends[-1]:]
            self._emit(ready)
        return len(text)

    def flush(self) -> None:
        """Pass on what is held (made safe) and flush the stream."""
        if self._pending:
            ready, self._pending = self._pending, ""
            self._emit(ready)
        self._stream.flush()

    def writelines(self, lines: Iterable[str]) -> None:
        """Write each line."""
        for line in lines:
            self.write(line)

    def _emit(self, text: str) -> None:
        safe = self._OWN.join(terminal_safe(part) for part in text.split(self._OWN))
        self._stream.write(scrub(safe))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


# -- finding traces ----------------------------------------------------------------------------


def _compact(text: str) -> str:
    return "".join(_ALNUM.findall(text)).casefold()


def _forms_of(secret: str) -> list[str]:
    """The letters and digits (case folded) of every form the secret is looked for in."""
    raw = secret.encode("utf-8")
    forms = [_compact(secret), _compact(secret)[::-1], raw.hex()]
    for offset in range(3):  # base64 of the key at each byte offset in a longer text
        encoded = base64.b64encode(b"\0" * offset + raw).decode("ascii")
        skip = (4 * offset + 2) // 3  # characters mixed with the bytes before
        forms.append(_compact(encoded[skip:-4]))
    return forms


def _trace_spans(text: str) -> list[tuple[int, int]]:
    """Spans of ``text`` (start, end) holding a trace of a registered secret, merged and sorted."""
    letters: list[str] = []
    where: list[int] = []  # index in text of each compact character
    words: list[tuple[int, int]] = []  # (compact start, compact end) of each run of letters and digits
    for match in _KEPT.finditer(text):
        start = len(letters)
        letters.extend(match.group().lower())  # ASCII only: one character each
        where.extend(range(match.start(), match.end()))
        words.append((start, len(letters)))
    compact = "".join(letters)
    spans: list[tuple[int, int]] = []
    followed: dict[tuple[int, int], int] = {}  # (form, diagonal) -> compact end of the trace found
    hits = [(i, hit) for step, seeds in zip(_SEED_STEPS, _seeds, strict=True)
            for i in range(len(compact) - step * (_SEED_LENGTH - 1))
            for hit in seeds.get(compact[i:i + step * (_SEED_LENGTH - 1) + 1:step], ())]
    for i, (form_index, j) in sorted(hits):
            diagonal = (form_index, i - j)
            if i < followed.get(diagonal, -1):
                continue
            found = _follow(compact, _forms[form_index], i, j)
            if found is None:
                continue
            followed[diagonal] = found[1]
            spans.append((where[found[0]], where[found[1] - 1] + 1))
    for c_start, c_end in words:
        word = compact[c_start:c_end]
        if c_end - c_start >= MIN_WORD and "*" not in word and any(word in form for form in _forms):
            spans.append((where[c_start], where[c_end - 1] + 1))
    return _merged(spans)


def _follow(compact: str, form: str, i: int, j: int) -> tuple[int, int] | None:
    """From a seed at compact[i] = form[j], the stretch following the form (compact start, end)."""
    def walk(step: int) -> list[int]:
        p, q, gap = i, j, 0
        matched: list[int] = []
        while 0 <= p < len(compact) and 0 <= q < len(form):
            if compact[p] == form[q]:
                matched.append(p)
                gap = 0
            else:
                gap += 1
                if gap > MAX_GAP:
                    break
            p, q = p + step, q + step
        # a lone match after a long gap at the far end is chance, not the key: the stretch ends before it
        while len(matched) > 1 and abs(matched[-1] - matched[-2]) > MAX_GAP:
            matched.pop()
        return matched

    ahead, behind = walk(1), walk(-1)
    if len(ahead) + len(behind) - 1 < MIN_RUN:  # the seed's first character counted twice
        return None
    return behind[-1], ahead[-1] + 1


def _merged(spans: list[tuple[int, int]]) -> list[tuple[int, int]]:
    merged: list[tuple[int, int]] = []
    for start, end in sorted(spans):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((start, end))
    return merged
