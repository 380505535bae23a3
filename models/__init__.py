"""The bundled models (one folder each: best_model.pth, config.yaml, model_card.json) and their speed/accuracy atlas
(atlas/engine.json), installed with the code as package data: `touchanything.app.sessions.bundled` finds them."""
