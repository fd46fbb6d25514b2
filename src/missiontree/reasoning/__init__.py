"""Reasoning: the model protocols, non-blocking calls, answer schemas and checks, and providers.

- :mod:`~missiontree.reasoning.protocols` — VisionLanguageModel, LanguageModel, Embedder.
- :mod:`~missiontree.reasoning.calls` — ModelCaller / ModelCall: submit, poll, time out, cancel.
- :mod:`~missiontree.reasoning.models` — Models: a mission's providers by role, call settings and
  bound caller, built once by the session.
- :mod:`~missiontree.reasoning.schemas` — pydantic answer schemas missions use.
- :mod:`~missiontree.reasoning.checks` — validation, retry-once, grounding of object ids.
- :mod:`~missiontree.reasoning.prompts` — the prompts missions send.
- providers: :mod:`~missiontree.reasoning.openai_provider`, :mod:`~missiontree.reasoning.offline_vlm`,
  :mod:`~missiontree.reasoning.offline_llm`, :mod:`~missiontree.reasoning.embedder`, registered by
  :mod:`~missiontree.reasoning.providers`; :mod:`missiontree.session.models` builds them from config.
"""
