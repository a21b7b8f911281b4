"""IEC 61850 (MMS) server: ``points`` is the pure point map, ``snapshot`` reads the database,
``server`` is the libiec61850 transport (pyiec61850-ng, optional extra ``hvcb[iec61850]``)."""
