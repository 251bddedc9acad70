"""Agents for AOASS (the recurrent TD3 agent lands with its own issue)."""
