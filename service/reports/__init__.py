"""What leaves the building about a breaker: the condition report (PDF) and the CSV exports.

``content`` reads what a report says from the database, ``verdicts`` judges the latest
operations against the breaker file's limits (pure), ``figures`` draws the plots (matplotlib),
``pdf`` lays the report out (fpdf2); ``exports`` streams the CSV files. docs/reports.md.
"""
