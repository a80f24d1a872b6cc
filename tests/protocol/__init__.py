"""The sans-IO protocol and the status model: frames, decoders, encoders, float32 fields."""
