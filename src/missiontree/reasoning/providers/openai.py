"""An OpenAI-compatible chat provider: OpenAI, vLLM, Ollama and llama.cpp servers alike.

One class, :class:`OpenAIChatModel`, is both a :class:`VisionLanguageModel` (``ask``: images sent
as base64 PNG/JPEG data URLs) and a :class:`LanguageModel` (``chat``). With a schema it asks for
structured output (``response_format: json_schema``, or ``json_object`` for servers without schema
support). It uses the official ``openai`` client (extra ``openai``), imported only when a provider
is built.

**The API key** is read from the environment variable named by ``api_key_env`` (default
``OPENAI_API_KEY``) when the provider is built. It is never written to a log, an error or a repr:
errors name the variable, not its value, and server messages are scrubbed of it (servers echo
masked keys in 401 answers; those are not repeated at all). **Answers are scrubbed too**, here at
the provider's boundary: a model (or a hostile server) that reflects the key — whole, in pieces,
reversed, re-cased, base64-encoded or partly masked (:mod:`missiontree.redact` lists the forms) —
has it replaced by ``***`` before the text leaves the provider, so no alarm record, tick log,
warning or retry prompt downstream can hold it. The key is also registered with
:mod:`missiontree.redact`, so the tick log, ``summary.json`` and the terminal scrub it too.

**Credentials in ``base_url``** (``http://user:secret@host/v1``, or a token in its query) are
never shown: messages and ``missiontree models`` name the server as ``http://***@host/v1``, and
the user name, password and query values are registered as secrets like the key.

**Redirects** are followed only within the server's own origin (scheme, host and port): a
redirect to another host would re-send the prompt, the camera frames and the key there, so it is
refused with a :class:`~missiontree.errors.ModelError`.

**Timeout.** The HTTP timeout is the role's ``timeout:`` in the models config (the same value the
mission's call handles use and ``missiontree models`` shows), handed to the factory by the model
wiring; without one, the ``calls: timeout:`` default, else 30 s. A server that hangs therefore
costs at most that long per attempt.

**Faults.** 429 and 5xx answers are retried with exponential backoff (honouring ``Retry-After``,
capped); a timeout raises :class:`~missiontree.errors.ModelTimeoutError`; an unreachable server, a
rejected key (401/403) or any other refusal raises :class:`~missiontree.errors.ModelError` naming
the provider, the server and the fix.

Options (a models-config section): ``model`` (required), ``base_url`` (default: OpenAI's),
``api_key_env`` (``OPENAI_API_KEY``; ``null`` for servers that need no key), ``max_retries`` (3),
``backoff`` (0.5 s, doubled each retry, at most ``max_backoff`` 8 s), ``temperature`` (0),
``max_tokens`` (512), ``image_format`` (``jpeg`` or ``png``), ``structured`` (``json_schema``,
``json_object`` or ``none``), ``name``.
"""

from __future__ import annotations

import base64
import os
import re
import time
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from missiontree.errors import BackendUnavailableError, ModelConfigError, ModelError, ModelTimeoutError
from missiontree.options import parse_provider_options
from missiontree.reasoning.protocols import Message, check_image
from missiontree.redact import redact_url, register_secret, scrub, url_secrets

_MASKED_KEY = re.compile(r"\b(sk|key|Bearer)[-_ ][A-Za-z0-9*_\-.]{4,}", re.IGNORECASE)
_MAX_BODY = 300


class OpenAIOptions(BaseModel):
    """The options of an ``openai`` provider section (see the module docstring)."""

    model_config = ConfigDict(extra="forbid")

    model: str = Field(min_length=1)
    base_url: str | None = None
    api_key_env: str | None = "OPENAI_API_KEY"
    timeout: float = Field(30.0, gt=0, allow_inf_nan=False)
    max_retries: int = Field(3, ge=0, le=10)
    backoff: float = Field(0.5, ge=0)
    max_backoff: float = Field(8.0, ge=0)
    temperature: float = Field(0.0, ge=0, le=2)
    max_tokens: int = Field(512, gt=0)
    image_format: Literal["jpeg", "png"] = "jpeg"
    structured: Literal["json_schema", "json_object", "none"] = "json_schema"
    name: str = "openai"


def _import_openai() -> Any:
    try:
        import openai
    except ImportError:
        raise BackendUnavailableError(
            "model provider 'openai' needs the official openai client: "
            "pip install 'missiontree[openai]'") from None
    return openai


class OpenAIChatModel:
    """A chat model behind an OpenAI-compatible HTTP API (vision and language).

    Build it with :meth:`from_options`; the key is read from the environment there.
    """

    def __init__(self, options: OpenAIOptions, api_key: str | None) -> None:
        openai = _import_openai()
        self.options = options
        self.name = options.name
        self.model = options.model
        self._openai = openai
        register_secret(api_key)
        for secret in url_secrets(options.base_url):
            register_secret(secret)
        self._client = openai.OpenAI(
            api_key=api_key or "no-key-needed",
            base_url=options.base_url,
            timeout=options.timeout,
            max_retries=0,  # retries are ours: backoff we control, and every attempt visible
            http_client=openai.DefaultHttpxClient(event_hooks={"response": [_refuse_cross_origin_redirect]}),
        )
        self.sleep = time.sleep  # replaced in tests

    @classmethod
    def from_options(cls, options: Mapping[str, Any], timeout: float | None = None) -> OpenAIChatModel:
        """Build from a models-config section.

        Args:
            options: The role's section (without ``provider``, ``latency`` and ``timeout``).
            timeout: The role's ``timeout:`` in seconds (HTTP timeout of each request); None keeps
                the ``timeout`` option (tests) or its 30 s default.

        Raises:
            ModelConfigError: An unknown or invalid option, or the key variable is unset.
            BackendUnavailableError: The ``openai`` extra is not installed.
        """
        if timeout is not None:
            options = {**options, "timeout": timeout}
        parsed = parse_provider_options(OpenAIOptions, options, "openai")
        key: str | None = None
        if parsed.api_key_env:
            key = os.environ.get(parsed.api_key_env)
            if not key:
                raise ModelConfigError(
                    f"model provider {parsed.name!r}: the environment variable {parsed.api_key_env} "
                    f"holding the API key is not set; export {parsed.api_key_env}=... or set "
                    "api_key_env: null for a local server that needs no key")
        return cls(parsed, key)

    def __repr__(self) -> str:
        return f"OpenAIChatModel(name={self.name!r}, model={self.model!r}, base_url={self._server!r})"

    @property
    def _server(self) -> str:
        return redact_url(str(self.options.base_url or "https://api.openai.com/v1"))

    # -- protocol methods ------------------------------------------------------------------------

    def ask(self, images: Sequence[np.ndarray], prompt: str, schema: type[BaseModel] | None = None) -> str:
        """Ask about images (sent as base64 data URLs); see VisionLanguageModel.ask."""
        if isinstance(images, np.ndarray):
            images = [images]
        parts: list[dict[str, Any]] = [{"type": "text", "text": prompt}]
        for image in images:
            parts.append({"type": "image_url", "image_url": {"url": self.data_url(image)}})
        return self._complete([{"role": "user", "content": parts}], schema)

    def chat(self, messages: Sequence[Message], schema: type[BaseModel] | None = None) -> str:
        """Answer a conversation; see LanguageModel.chat."""
        wire: list[dict[str, Any]] = []
        for message in messages:
            if message.images:
                parts: list[dict[str, Any]] = [{"type": "text", "text": message.content}]
                parts += [{"type": "image_url", "image_url": {"url": self.data_url(i)}}
                          for i in message.images]
                wire.append({"role": message.role, "content": parts})
            else:
                wire.append({"role": message.role, "content": message.content})
        return self._complete(wire, schema)

    def check(self) -> str:
        """Ping the server (list its models); return a one-line description or raise ModelError."""
        models = self._with_retries(lambda: self._client.models.list(), "list models")
        served = [self.scrub_answer(str(m.id))[:80] for m in getattr(models, "data", [])]
        note = "" if not served or self.model in served else (
            f"; note: {self.model!r} is not among the served models {served[:5]}")
        return (f"{self.model} at {self._server} ({len(served)} models served, HTTP timeout "
                f"{self.timeout:g} s){note}")

    @property
    def timeout(self) -> float:
        """The HTTP timeout of each request, seconds."""
        return float(self.options.timeout)

    def scrub_answer(self, text: str) -> str:
        """``text`` with every trace of the API key or the URL's credentials as ``***``."""
        return scrub(text)

    def data_url(self, image: np.ndarray) -> str:
        """The image as a base64 PNG or JPEG data URL."""
        rgb = check_image(image, self.name)
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        ext = ".png" if self.options.image_format == "png" else ".jpg"
        ok, buffer = cv2.imencode(ext, bgr)
        if not ok:
            raise ModelError(f"{self.name}: could not encode an image of shape {rgb.shape} as {ext}")
        mime = "image/png" if ext == ".png" else "image/jpeg"
        return f"data:{mime};base64,{base64.b64encode(buffer.tobytes()).decode('ascii')}"

    # -- the request -----------------------------------------------------------------------------

    def _complete(self, messages: list[dict[str, Any]], schema: type[BaseModel] | None) -> str:
        request: dict[str, Any] = {
            "model": self.model, "messages": messages,
            "temperature": self.options.temperature, "max_tokens": self.options.max_tokens,
        }
        if schema is not None and self.options.structured == "json_schema":
            request["response_format"] = {"type": "json_schema", "json_schema": {
                "name": schema.__name__, "schema": schema.model_json_schema(), "strict": False}}
        elif schema is not None and self.options.structured == "json_object":
            request["response_format"] = {"type": "json_object"}
        if schema is not None and self.options.structured != "json_schema":
            schema_text = str(schema.model_json_schema())
            messages[0:0] = [{"role": "system", "content": f"Answer with JSON matching: {schema_text}"}]
        response = self._with_retries(lambda: self._client.chat.completions.create(**request), "chat")
        try:
            content = response.choices[0].message.content
        except (AttributeError, IndexError, TypeError):
            raise ModelError(
                f"{self.name}: the server at {self._server} answered without a message "
                "(no choices); check that it serves the chat completions API") from None
        if content is None:
            refusal = getattr(response.choices[0].message, "refusal", None)
            why = f" (refusal: {self.scrub_answer(str(refusal))[:_MAX_BODY]})" if refusal else ""
            raise ModelError(f"{self.name}: the model gave no text{why}")
        return self.scrub_answer(str(content))

    def _with_retries(self, send: Any, what: str) -> Any:
        openai = self._openai
        attempt = 0
        while True:
            try:
                return send()
            except openai.APITimeoutError:
                raise ModelTimeoutError(
                    f"{self.name}: {what} at {self._server} took longer than {self.options.timeout:g} s; "
                    "raise timeout in the models config or use a faster model") from None
            except CrossOriginRedirectError as exc:  # raised by the HTTP client's response hook
                raise ModelError(f"{self.name}: {what} at {self._server}: {exc}; set base_url to the server "
                                 "that answers") from None
            except openai.APIConnectionError as exc:
                if isinstance(exc.__cause__, CrossOriginRedirectError):
                    raise ModelError(f"{self.name}: {what} at {self._server}: {exc.__cause__}; set base_url "
                                     "to the server that answers") from None
                raise ModelError(
                    f"{self.name}: cannot reach the server at {self._server} "
                    f"({self._scrub(str(exc.__cause__ or exc))}); start the server or fix base_url "
                    "in the models config") from None
            except openai.APIStatusError as exc:
                status = exc.status_code
                if (status == 429 or status >= 500) and attempt < self.options.max_retries:
                    self.sleep(self._delay(attempt, exc))
                    attempt += 1
                    continue
                raise self._status_error(exc, what, attempt) from None
            except openai.OpenAIError as exc:
                raise ModelError(f"{self.name}: {what} failed: {self._scrub(str(exc))}") from None

    def _delay(self, attempt: int, exc: Any) -> float:
        delay = self.options.backoff * (2 ** attempt)
        retry_after = getattr(getattr(exc, "response", None), "headers", {}).get("retry-after")
        try:
            if retry_after is not None:
                delay = max(delay, float(retry_after))
        except ValueError:
            pass
        return min(delay, self.options.max_backoff)

    def _status_error(self, exc: Any, what: str, retries: int) -> ModelError:
        status = exc.status_code
        if status in (401, 403):
            env = self.options.api_key_env
            fix = (f"set {env} to a valid key for {self._server}" if env
                   else f"the server at {self._server} wants a key: set api_key_env to the variable "
                        "holding it")
            return ModelError(f"{self.name}: the server at {self._server} rejected the API key "
                              f"(HTTP {status}); {fix}")
        body = self._scrub(_body_text(exc))
        tried = f" after {retries + 1} attempts" if retries else ""
        if status == 429:
            fix = "the server is rate limiting; lower the call rate or raise max_retries"
        elif status >= 500:
            fix = "the server failed; check its logs"
        elif status == 404:
            fix = f"check the model name {self.model!r} and base_url"
        else:
            fix = "check the request options (model, structured) against what the server supports"
        return ModelError(
            f"{self.name}: {what} at {self._server} failed with HTTP {status}{tried}: {body}; {fix}")

    def _scrub(self, text: str) -> str:
        return _MASKED_KEY.sub("***", self.scrub_answer(text))[:_MAX_BODY]


class CrossOriginRedirectError(Exception):
    """A redirect to another origin (raised inside the HTTP client, reported as a ModelError)."""


def _origin(url: Any) -> tuple[str, str, int | None]:
    scheme = str(url.scheme).lower()
    return scheme, str(url.host).lower(), url.port or {"http": 80, "https": 443}.get(scheme)


def _refuse_cross_origin_redirect(response: Any) -> None:
    """HTTP client response hook: a redirect is followed only to the same scheme, host and port.

    Following it elsewhere would re-send the prompt and camera frames (307/308 keep the body) to a
    server nobody configured.
    """
    if not response.has_redirect_location:
        return
    here = response.request.url
    try:
        there = here.join(response.headers["Location"])
    except Exception:  # noqa: BLE001 - a Location that cannot be read is refused as well
        raise CrossOriginRedirectError("the server answered with a redirect whose address cannot be read; "
                                       "not followed") from None
    if _origin(there) != _origin(here):
        raise CrossOriginRedirectError(
            f"the server redirected (HTTP {response.status_code}) to another origin, "
            f"{redact_url(str(there.copy_with(path='/', query=None, fragment=None)))}; not followed "
            "(the request holds the prompt and the camera frames)")


def _body_text(exc: Any) -> str:
    body = getattr(exc, "body", None)
    if isinstance(body, Mapping):
        error = body.get("error")
        if isinstance(error, Mapping) and error.get("message"):
            return str(error["message"])
        if body.get("message"):
            return str(body["message"])
    return str(getattr(exc, "message", "") or exc)
