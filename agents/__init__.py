"""Baseline brake controllers for the brakegym environments: a PID deceleration controller
(:mod:`agents.pid`) and stable-baselines3 PPO/SAC agents (:mod:`agents.rl`)."""
