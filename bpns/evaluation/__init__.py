"""Evaluating approaches on held-out tasks, and what an evaluation leaves behind."""
