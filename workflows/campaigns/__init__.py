"""Shipped campaign configurations (package data): one TOML per production training set or ringdown sweep.

List them with ``bubblecal.workflows.campaign.available_campaigns()``; run one with
``bubblecal sim campaign NAME`` (the store goes to ``./NAME.store`` unless ``--store`` is given).
"""
