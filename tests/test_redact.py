"""Tests of missiontree.redact: every form of a secret scrubbed, URLs without credentials, safe terminal."""

from __future__ import annotations

import base64
import io
from collections.abc import Iterator

import pytest

from missiontree.redact import (
    SafeTerminal,
    forget_secrets,
    redact_url,
    register_secret,
    scrub,
    scrub_data,
    terminal_safe,
    url_secrets,
)

KEY = "sk-proj-Ab3dEf9hIjK1mNoPqR5tUvW7yZa2Cd4Fg6Hi8"


@pytest.fixture(autouse=True)
def _key() -> Iterator[None]:
    forget_secrets()
    register_secret(KEY)
    yield
    forget_secrets()


def _masked(text: str, every: int) -> str:
    return "".join("*" if i % every == every - 1 else c for i, c in enumerate(text))


FORMS = {
    "whole": f"the key is {KEY}.",
    "pieces of 5 with spaces": " ".join(KEY[i:i + 5] for i in range(0, len(KEY), 5)),
    "pieces of 3 quoted": ", ".join(repr(KEY[i:i + 3]) for i in range(0, len(KEY), 3)),
    "one character a line": "\n".join(KEY),
    "pieces of 11 between words": f"part one {KEY[:11]} part two {KEY[11:22]} part three {KEY[22:33]}",
    "base64": base64.b64encode(f"here: {KEY}".encode()).decode(),
    "base64 url-safe, offset 2": base64.urlsafe_b64encode(f"ab{KEY}".encode()).decode(),
    "reversed": KEY[::-1],
    "upper-cased": KEY.upper(),
    "hex": KEY.encode().hex(),
    "31 of 42 characters, masked": "invalid api key " + _masked(KEY[:42], 4),
}


@pytest.mark.parametrize("form", FORMS)
def test_every_form_of_the_key_is_scrubbed(form: str) -> None:
    """No run of 8 of the key's letters and digits survives scrubbing, whatever form the key took."""
    cleaned = scrub(FORMS[form])
    compact = "".join(c for c in cleaned.lower() if c.isalnum())
    for candidate in (KEY.lower(), KEY[::-1].lower()):
        letters = "".join(c for c in candidate if c.isalnum())
        assert not any(letters[i:i + 8] in compact for i in range(len(letters) - 7)), cleaned
    assert "***" in cleaned


def test_ordinary_text_is_left_alone() -> None:
    """Text sharing a few characters with the key (its prefix, short words, numbers) is unchanged."""
    text = "short sk-proj ok; the robot saw 12345678 chairs, Ab3 and dEf9 look fine; SAFE"
    assert scrub(text) == text


def test_scrub_data_keeps_the_shape() -> None:
    """Strings inside nested data are scrubbed; numbers and keys of the structure stay."""
    data = {"reason": f"bad {KEY}", "n": 3, "list": [KEY.upper(), 1.5]}
    assert scrub_data(data) == {"reason": "bad ***", "n": 3, "list": ["***", 1.5]}


def test_url_credentials_are_redacted_and_registered() -> None:
    """A base_url's user, password and query values are hidden in the shown URL and listed as secrets."""
    url = "http://robot:hunter2-Secret@10.0.0.5:8000/v1?token=tok-123456789"
    assert redact_url(url) == "http://***@10.0.0.5:8000/v1?token=***"
    assert set(url_secrets(url)) == {"robot", "hunter2-Secret", "tok-123456789"}


def test_terminal_text_shows_escape_sequences_escaped() -> None:
    """A title-setting and a screen-clearing sequence come out as visible escapes, newlines stay."""
    assert terminal_safe("a\x1b]0;owned\x07b\x1b[2Jc\nd\u202e") == "a\\x1b]0;owned\\x07b\\x1b[2Jc\nd\\u202e"


def test_safe_terminal_keeps_the_progress_line_and_scrubs() -> None:
    """The terminal wrapper passes the progress line's own sequences and scrubs the key."""
    out = io.StringIO()
    terminal = SafeTerminal(out)
    terminal.write("\r50 %\x1b[K")
    terminal.write(f"key {KEY}\x1b[31m\n")
    assert out.getvalue() == "\r50 %\x1b[Kkey ***\\x1b[31m\n"


def test_safe_terminal_scrubs_a_key_written_in_pieces() -> None:
    """A key written in several write() calls (as json.dump does) is scrubbed once the line is whole."""
    out = io.StringIO()
    terminal = SafeTerminal(out)
    for piece in ('{"key": "', KEY[:10], KEY[10:25], KEY[25:], '"}'):
        terminal.write(piece)
    terminal.flush()
    assert out.getvalue() == '{"key": "***"}'


def test_a_short_url_password_is_scrubbed_from_urls_in_text() -> None:
    """A password too short to look for in prose is still removed wherever a URL carries it."""
    register_secret("pw")
    text = "GET http://u:pw@10.0.0.5/v1 failed; see https://host/x"
    assert scrub(text) == "GET http://***@10.0.0.5/v1 failed; see https://host/x"
