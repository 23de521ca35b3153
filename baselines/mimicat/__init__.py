"""The bundled MimiCAT reference (arXiv 2511.18370), re-implemented from the paper."""
