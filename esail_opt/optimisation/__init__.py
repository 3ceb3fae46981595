"""Layer 3: problem definition, transcription to an NLP, the Ipopt solve and its verification."""
