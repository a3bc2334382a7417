"""Baseline brake controllers for the brakegym environments: a PID deceleration controller
(:mod:`.pid`) and stable-baselines3 PPO/SAC agents (:mod:`.rl`), with the trained policies that
ship with brakegym (``policies/``).

In the repository this is the top-level ``agents/`` folder; installed, it is ``brakegym.agents``.
"""
