"""Task panels: the brush panel (:mod:`.brush`) and the assembly panel (:mod:`.assembly`);
how they close (:mod:`.closing`) and their titles (:mod:`.titles`)."""
