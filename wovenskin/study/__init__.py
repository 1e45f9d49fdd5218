"""User studies as data: study definitions, counterbalanced plans, trial logs and reports.

``definition`` reads ``study.toml``; ``counterbalance`` orders interfaces and tasks per
participant (balanced Latin squares); ``recorder`` writes a trial's logs crash-safely and
``runner`` feeds it from a live session on a task scene; ``questionnaires`` scores
NASA-TLX and SUS; ``reader`` loads a study folder back; ``stats``, ``tables``, ``plots``
and ``report`` build the report; ``simulate`` runs whole studies with simulated operators
(labelled simulated) and ``synthetic`` writes made-up trials (labelled synthetic).
The folder format is documented in docs/study.md.
"""
