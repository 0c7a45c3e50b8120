"""The on-board DB bundle: what a train loads to drive a line, and what it checks first.

Takes a validated line and the published datasets of the tables and stopping
steps; gives one signed, reproducible ``<line>_<direction>_<train_type>.pdb``
per direction × train type, and the verdict on one before a vehicle loads it
(``docs/bundles.md``). The modules, in the order of a build:

``atsp``       ATS-P data: pattern starts, overwrite flags, beacon correction flags (pure)
``assemble``   a line's tables for one direction and train type, plus the steps' datasets
``contents``   declared schemas of those tables and the checks between them
``manifest``   the signed manifest: target, release (version, build time, expiry), files
``archive``    the canonical tar the members are packed in, and its strict reader
``signing``    Ed25519 keys and signatures
``container``  builds, signs and atomically writes the bundles (``build_line``)
``verify``     what a vehicle checks before loading a bundle (``verify_bundle``)
"""
