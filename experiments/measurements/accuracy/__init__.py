"""Accuracy: identification, inverse models, the bound's bracket, the gradient clairvoyant, reward separation."""
