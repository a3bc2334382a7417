"""Baseline brake controllers for the brakegym environments: a PID deceleration controller
(:mod:`.pid`), stable-baselines3 PPO/SAC agents (:mod:`.rl`), with the trained policies that
ship with brakegym (``policies/``), the reference wheel-slide protection (:mod:`.wsp`) and the WSP
controllers of one kind, reference, none or a trained policy (:mod:`.wsp_policy`).

In the repository this is the top-level ``agents/`` folder; installed, it is ``brakegym.agents``.
"""
