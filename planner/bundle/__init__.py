"""The on-board DB bundle: ATS-P data, assembly of a line's tables into bundle
tables, the container (tar, manifest, verification) and Ed25519 signing.

Takes the published datasets of a run; gives signed ``.tar`` bundles and
verification reports.
"""
