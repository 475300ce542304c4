"""Offline work without DDS: lockstep scenario runs, replay, bags."""
