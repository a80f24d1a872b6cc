"""The package as a whole: layering, import graph, public API, options, docs, examples, wheel."""
