"""Evaluation: campaigns and paper experiments against ground truth (uses sim_vehicle; see
docs/architecture.md).

Layers, each importing only the ones above it::

    records, scenarios, configs, runner, data   what runs produce; what they fly; how the
                                                monitor is configured; the one process pool;
                                                where the real data is
    scoring, report                             scores against truth; Markdown, CSV, PNG
    runs                                        one run through the MAVLink path, scored
    campaign, sim_checks, papers/*              preset-set campaigns and the experiments,
                                                one module per paper (+ its real-data one)
    registry                                    names for ``gcs-monitor evaluate``
"""
