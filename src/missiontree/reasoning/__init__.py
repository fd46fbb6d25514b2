"""Reasoning: the model protocols, non-blocking calls, answer schemas and checks, and providers.

- :mod:`~missiontree.reasoning.protocols` — VisionLanguageModel, LanguageModel, Embedder.
- :mod:`~missiontree.reasoning.calls` — ModelCaller / ModelCall: submit, poll, time out, cancel.
- :mod:`~missiontree.reasoning.models` — Models: a mission's providers by role, call settings and
  bound caller, built once by the session.
- :mod:`~missiontree.reasoning.schemas` — pydantic answer schemas missions use.
- :mod:`~missiontree.reasoning.checks` — validation, retry-once, grounding of object ids.
- :mod:`~missiontree.reasoning.prompts` — the prompts missions send.
- :mod:`~missiontree.reasoning.providers` — the providers, one module each (``openai``,
  ``offline_vlm``, ``offline_llm``, ``offline_scene``; the embedder is
  :mod:`~missiontree.reasoning.embedder`), and their one registry;
  :mod:`missiontree.session.models` builds them from config.
"""
