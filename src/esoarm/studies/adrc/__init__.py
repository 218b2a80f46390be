"""ADRC forms, tunings and add-ons side by side: tracking, chatter, the transport delay held."""
