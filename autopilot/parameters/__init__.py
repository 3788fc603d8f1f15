"""Parameters (SPEC §8): the store every component declares against (``store``) and the declarations of navigation,
the commander, the land detector and the failsafes (``nav_decls``). The whole schema and the live bindings are
gathered at the top level (``autopilot.param_schema``, ``autopilot.param_binding``)."""
