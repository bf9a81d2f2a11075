"""evolution: a generic ask/tell evolution engine (GA, CMA-ES, quality diversity) with resumable runs.

A library of its own: it sees only *problems* (candidates in, objectives and measures out) and imports nothing from
``structgen``. The engine arrives with issue 4.
"""
