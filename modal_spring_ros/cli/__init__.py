"""Console scripts, one module each, named after the script; ``common`` holds what they share."""
