"""NUSkin receiver event words: the byte format, a streaming decoder, the clock model."""
