"""High-level planners: the in-context VLM planner (with / without failure reasoning) and offline planners.

Modules: ``schema`` (answer schemas and validation), ``prompts`` (prompt data files and loader), ``vlm``
(OpenAI-compatible client and VLM planner), ``record`` (call recording and replay), ``instruction``
(instruction -> clip order) and ``planners`` (the Planner interface, offline planners, ``make_planner``).
Import from the modules; this package imports nothing so that the offline parts load without the SDK.
"""
