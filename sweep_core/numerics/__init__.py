"""How a scene moves: linearised rows (:mod:`.constraints`), the projection (:mod:`.projection`),
the schemes (:mod:`.schemes`), Brownian increments (:mod:`.noise`, :mod:`.paths`), the 1-D
Skorokhod map (:mod:`.skorokhod`) and the stepping loop (:mod:`.simulator`)."""
