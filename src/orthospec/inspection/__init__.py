"""The visual inspection grid (Grid-Orto; JRC Table 6 QCR 13, §6.3, §8.4, Table 7, Table 11).

``orthospec inspect grid`` writes a GeoPackage of square cells over the sampled orthoimages into the
checker's folder (grid.py); the checker marks each cell in a GIS (inspected, defect classes of
specs/inspection.yaml, a comment); ``check`` reads the marked grid back as the checker's evidence:
per-image verdicts of the manual rules it answers, and the share of the sampled area inspected.
Each cell carries the image id and the image's SHA-256 written by the tool, so a mark never carries
over to other pixels (issue 29 items 3 and 4).
"""
