"""The paper's GNN baselines, whole: graph encoding (:mod:`.graphs`), the graph network
(:mod:`.gnn`), the metacontroller and the behavioural-cloning policy (:mod:`.gnn_meta`,
:mod:`.gnn_bc`), learning them beside the skills (:mod:`.learn`), their files
(:mod:`.files`) and the approaches that solve tasks with them (:mod:`.approaches`)."""
