"""The thesis as data: its numbers, its findings, its scenes and the tables built beside ours.

``numbers``
    The transcribed tables (``data/thesis_tables.json``): every report's "thesis" column.
``findings``
    What the thesis found (``data/thesis_findings.json``) and :func:`~sparselt.thesis.findings.judge`.
``scenes``
    The thesis's scenes and ours that stand for them, with San Miguel's thin lens: the one correspondence.
``tables``
    Thesis Tables 6.1, 6.2/6.3 and 8.1/8.2 beside ours, each built by one function from plain rows, for a
    single run's report and for ``sparselt reproduce`` alike.
"""
