"""Monitoring a fleet across processes and hosts on Zenoh.

``gcs-monitor bridge`` puts the raw MAVLink frames of a link onto ``mavlink/<sysid>/rx``;
``gcs-monitor worker`` processes subscribe to their share of the fleet, run the full pipeline
per vehicle and publish the one alarm stream and health; workers announce themselves with
Zenoh liveliness tokens, and when one disappears the others take its vehicles over
(:mod:`gcs_monitor.fleet.worker`). Which worker owns a vehicle is a pure function of the live
workers (:mod:`gcs_monitor.fleet.ownership`), so every worker computes the same answer without a
coordinator. Zenoh routers (``gcs-monitor router``, or ``zenohd`` at a site) carry everything;
nothing here touches Zenoh directly (:mod:`gcs_monitor.link.zenoh_bus` does).
"""
