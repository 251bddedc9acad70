"""Agents for AOASS: a general recurrent TD3 (TD3-LSTM) for Stable-Baselines3."""

from agents.buffers import SequenceReplayBuffer, SequenceReplayBufferSamples
from agents.policies import MlpLstmPolicy, RecurrentTD3Policy
from agents.recurrent_td3 import RecurrentTD3

__all__ = [
    "MlpLstmPolicy",
    "RecurrentTD3",
    "RecurrentTD3Policy",
    "SequenceReplayBuffer",
    "SequenceReplayBufferSamples",
]
