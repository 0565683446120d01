"""Monitored families: one package each (``imu``, ``airdata``), driven by the pipeline through
the protocol of :mod:`gcs_monitor.families.base` and listed in
:mod:`gcs_monitor.families.registry`."""
