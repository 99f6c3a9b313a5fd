"""What every stage shares: storage, the executor and item loop, failures, errors, ids, paths, params."""
