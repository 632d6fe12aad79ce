"""Memory: the estimates that refuse an option against what it takes."""
