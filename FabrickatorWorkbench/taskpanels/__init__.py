"""Task panels: the brush panel (:mod:`.brush`) and the assembly panel (:mod:`.assembly`)."""
