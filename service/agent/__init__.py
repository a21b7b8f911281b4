"""The edge agent (``hvcb agent``): acquisition at the substation, forwarding to a central hvcb."""
