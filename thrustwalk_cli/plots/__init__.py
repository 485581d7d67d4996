"""Matplotlib figures from plain figure data; imports no other thrustwalk layer."""
