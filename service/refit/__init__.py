"""Refitting stored operations (``hvcb refit``, POST /api/v1/refits): resumable runs whose new
results supersede, and keep, the old ones."""
